// lancer: the command-line front end. Exit codes: 0 success, 2 bad input (file, flag), 1 a failed check
// (structures that disagree in the bench) or an internal error.
#include <fmt/core.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <new>

#include "commands.hpp"
#include "common.hpp"
#include "lancer/io.hpp"

int main(int argc, char** argv) {
    CLI::App app{
        "lancer: ray-tracing kernels (Pluecker-connected octree, BVH, kd-tree, grid) and a renderer"};
    app.require_subcommand(1);
    lancer::cli::add_render_command(app);
    lancer::cli::add_info_command(app);
    lancer::cli::add_rays_command(app);
    lancer::cli::add_stats_command(app);
    lancer::cli::add_bench_command(app);
    lancer::cli::add_convert_command(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& error) {
        const int code = app.exit(error);
        return code == 0 ? 0 : 2;
    } catch (const lancer::LoadError& error) {
        fmt::print(stderr, "lancer: {}\n", error.what());
        return 2;
    } catch (const lancer::cli::InputError& error) {
        fmt::print(stderr, "lancer: {}\n", error.what());
        return 2;
    } catch (const std::bad_alloc&) {
        // Past loading and building (which say which phase failed): rays, images, the bench's records.
        fmt::print(stderr, "lancer: {}\n", lancer::cli::out_of_memory("the command", "running").what());
        return 2;
    } catch (const lancer::cli::CheckFailure& error) {
        fmt::print(stderr, "lancer: {}\n", error.what());
        return 1;
    } catch (const std::exception& error) {
        fmt::print(stderr, "lancer: internal error: {}\n", error.what());
        return 1;
    }
    return 0;
}
