// One function per subcommand: each adds its options and its callback to the application.
#pragma once

#include <CLI/CLI.hpp>

namespace lancer::cli {

void add_render_command(CLI::App& app);
void add_info_command(CLI::App& app);
void add_rays_command(CLI::App& app);
void add_nearest_command(CLI::App& app);
void add_stats_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_convert_command(CLI::App& app);

}  // namespace lancer::cli
