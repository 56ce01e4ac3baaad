// lancer convert SCENE --accel plucker -o FILE.plo: builds the Pluecker octree once and writes it with its
// geometry (src/accel/plucker/serialise.hpp), for `lancer render FILE.plo` and `lancer rays FILE.plo`.
#include <fmt/core.h>

#include <memory>

#include "accel/plucker/plucker.hpp"
#include "accel/plucker/serialise.hpp"
#include "commands.hpp"
#include "common.hpp"

namespace lancer::cli {
namespace {

struct ConvertOptions {
    std::string scene_file;
    std::string output;
    AccelChoice accel;
};

void run(const ConvertOptions& options) {
    if (options.accel.name != "plucker")
        throw InputError("convert writes the plucker octree only: use --accel plucker (got '" +
                         options.accel.name + "')");
    const LoadedScene loaded = load_timed(options.scene_file);
    const SceneGeometry geometry(loaded.scene);
    const BuiltAccel built = build_timed(options.accel, geometry.view());
    const auto& accel = static_cast<const PluckerAccel&>(*built.accel);
    Stopwatch watch;
    try {
        plucker::write_plucker_file(options.output, geometry.view(), accel.layout(),
                                    options.accel.build_options().triangle_test);
    } catch (const plucker::PluckerFileError& error) {
        throw InputError(error.what());
    }
    const AccelStats stats = accel.stats();
    fmt::print("{}: {} primitives, {} leaves (max depth {}), build {:.1f} ms\n", options.scene_file,
               geometry.view().size(), stats.leaves, stats.max_depth, built.build_ms);
    fmt::print("wrote {} ({:.2f} MB structure) in {:.1f} ms\n", options.output,
               static_cast<double>(accel.memory_bytes()) / (1024.0 * 1024.0), watch.elapsed_ms());
}

}  // namespace

void add_convert_command(CLI::App& app) {
    auto options = std::make_shared<ConvertOptions>();
    options->accel.name = "plucker";
    CLI::App* command =
        app.add_subcommand("convert", "Build the Pluecker octree of a scene and write it to a .plo file");
    command->add_option("scene", options->scene_file, "Mesh or scene file")->required();
    command->add_option("-o,--output", options->output, "The .plo file to write")->required();
    options->accel.add_options(*command);
    command->callback([options] { run(*options); });
}

}  // namespace lancer::cli
