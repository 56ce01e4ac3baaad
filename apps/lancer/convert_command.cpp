// lancer convert SCENE --accel plucker -o FILE.plo: builds the Plücker octree once and writes it with its
// geometry (World::save_structure), for `lancer render FILE.plo` and `lancer rays FILE.plo`.
#include <fmt/core.h>

#include <memory>

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
    const PreparedScene prepared = prepare_scene(options.scene_file, options.accel);
    const World& world = prepared.world;
    Stopwatch watch;
    try {
        world.save_structure(options.output);
    } catch (const StructureFileError& error) {
        throw InputError(error.what());
    }
    const AccelStats stats = world.accel().stats();
    fmt::print("{}: {} primitives, {} leaves (max depth {}), build {:.1f} ms\n", options.scene_file,
               world.geometry().view().size(), stats.count("leaves"), stats.count("max_depth"),
               prepared.build_ms);
    fmt::print("wrote {} ({:.2f} MB structure) in {:.1f} ms\n", options.output,
               static_cast<double>(world.accel().memory_bytes()) / (1024.0 * 1024.0), watch.elapsed_ms());
}

}  // namespace

void add_convert_command(CLI::App& app) {
    auto options = std::make_shared<ConvertOptions>();
    options->accel.name = "plucker";
    CLI::App* command =
        app.add_subcommand("convert", "Build the Plücker octree of a scene and write it to a .plo file");
    command->add_option("scene", options->scene_file, "Mesh or scene file")->required();
    command->add_option("-o,--output", options->output, "The .plo file to write")->required();
    options->accel.add_options(*command);
    command->callback([options] { run(*options); });
}

}  // namespace lancer::cli
