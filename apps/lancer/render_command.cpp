// lancer render [SCENE]: renders a scene (the authored default scene when none is given) to PNG.
#include <fmt/core.h>

#include <map>
#include <memory>

#include "commands.hpp"
#include "common.hpp"
#include "lancer/render.hpp"

namespace lancer::cli {
namespace {

struct RenderCommandOptions {
    std::string scene_file = LANCER_DEFAULT_SCENE;
    std::string output = "render.png";
    std::string size;
    ShadingMode mode = ShadingMode::Flat;
    AccelChoice accel;
    int threads = 0;
};

void run(const RenderCommandOptions& options) {
    const PreparedScene prepared = prepare_scene(options.scene_file, options.accel);
    const LoadedScene& loaded = prepared.loaded;
    const Scene& scene = loaded.scene;
    const SceneGeometry& geometry = *prepared.geometry;
    const BuiltAccel& built = prepared.built;

    Camera camera = scene.camera ? *scene.camera : canonical_view(scene.bounds());
    if (!options.size.empty()) std::tie(camera.width, camera.height) = parse_size(options.size);

    RenderOptions render_options;
    render_options.mode = options.mode;
    render_options.threads = options.threads;
    render_options.progress = stderr_is_terminal();
    RenderStats stats;
    const Image image = render(scene, geometry, *built.accel, camera, render_options, &stats);
    try {
        write_png(image, options.output);
    } catch (const std::runtime_error& error) {
        throw InputError(error.what());
    }

    const double mrays_per_s = static_cast<double>(stats.primary_rays) / (stats.trace_ms * 1e3);
    fmt::print("{}: {}x{}, {} triangles, {} spheres, {} planes\n", options.scene_file, image.width,
               image.height, scene.triangle_count(), scene.spheres.size(), scene.planes.size());
    fmt::print("load {:.1f} ms, accel {} build {:.1f} ms, trace {:.1f} ms, {:.2f} Mrays/s\n", loaded.load_ms,
               built.accel->name(), built.build_ms, stats.trace_ms, mrays_per_s);
    if (options.mode == ShadingMode::Heatmap) {
        const double rays = static_cast<double>(stats.counters.rays);
        fmt::print("per primary ray: {:.2f} nodes visited, {:.2f} primitives tested\n",
                   static_cast<double>(stats.counters.nodes_visited) / rays,
                   static_cast<double>(stats.counters.prims_tested) / rays);
    }
    fmt::print("wrote {}\n", options.output);
}

}  // namespace

void add_render_command(CLI::App& app) {
    auto options = std::make_shared<RenderCommandOptions>();
    CLI::App* command = app.add_subcommand("render", "Render a scene to PNG");
    command->add_option(
        "scene", options->scene_file,
        "Scene or mesh file, or a .plo octree from `lancer convert` (default: the demo scene)");
    command->add_option("-o,--output", options->output, "PNG file to write")->capture_default_str();
    command->add_option("--size", options->size, "Image size WIDTHxHEIGHT (default: the scene's camera)");
    const std::map<std::string, ShadingMode> modes = {{"flat", ShadingMode::Flat},
                                                      {"normal", ShadingMode::Normal},
                                                      {"depth", ShadingMode::Depth},
                                                      {"heatmap", ShadingMode::Heatmap}};
    command->add_option("--mode", options->mode, "Shading: flat, normal, depth or heatmap (nodes per ray)")
        ->transform(CLI::CheckedTransformer(modes, CLI::ignore_case));
    options->accel.add_options(*command);
    command->add_option("--threads", options->threads, "Threads (0 = all)")->check(CLI::NonNegativeNumber);
    command->callback([options] { run(*options); });
}

}  // namespace lancer::cli
