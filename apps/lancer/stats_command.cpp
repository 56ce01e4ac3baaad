// lancer stats MESH --accel NAME [--json FILE] [--rays]: what a structure looks like once built (the
// operation counts of Ferreira & Mendoza (2011), their Figure 6 in numbers), and with --rays its cost per
// primary ray.
#include <fmt/core.h>
#include <fmt/os.h>

#include <algorithm>
#include <memory>
#include <string_view>

#include "commands.hpp"
#include "common.hpp"
#include "lancer/camera.hpp"

namespace lancer::cli {
namespace {

struct StatsOptions {
    std::string scene_file;
    AccelChoice accel;
    std::string json_file;
    bool rays = false;
    std::string size = "1024x1024";
};

struct RayCost {
    std::uint64_t rays = 0, hits = 0;
    TraversalCounters counters;
    double trace_ms = 0.0;
};

std::string figure_text(const AccelFigure& figure) {
    if (figure.whole) return fmt::format("{}", static_cast<std::uint64_t>(figure.value));
    return fmt::format("{:.3f}", figure.value);
}

// A count as a JSON integer, any other value in the shortest form that reads back the same.
std::string figure_json(const AccelFigure& figure) {
    if (figure.whole) return fmt::format("{}", static_cast<std::uint64_t>(figure.value));
    return fmt::format("{}", figure.value);
}

// The canonical view of shared/bench/VIEWS.md (or the scene's camera), traced once with counters on.
RayCost trace_view(const Accel& accel, const Scene& scene, int width, int height) {
    Camera camera = scene.camera ? *scene.camera : canonical_view(scene.bounds(), width, height);
    camera.width = width, camera.height = height;
    const PinholeCamera pinhole(camera);
    std::vector<Ray> rays;
    rays.reserve(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
    for (int j = 0; j < height; ++j) {
        for (int i = 0; i < width; ++i) {
            rays.push_back(pinhole.generate(static_cast<float>(i) + 0.5f, static_cast<float>(j) + 0.5f));
        }
    }
    std::vector<Hit> hits(rays.size());
    RayCost cost;
    Stopwatch watch;
    accel.intersect(rays, hits, &cost.counters);
    cost.trace_ms = watch.elapsed_ms();
    cost.rays = rays.size();
    for (const Hit& hit : hits)
        cost.hits += hit.hit() ? 1 : 0;
    return cost;
}

void run(const StatsOptions& options) {
    const PreparedScene prepared = prepare_scene(options.scene_file, options.accel);
    const Accel& accel = prepared.world.accel();
    const AccelStats stats = accel.stats();
    const std::size_t primitives = prepared.world.geometry().view().size();
    const double memory_mb = static_cast<double>(accel.memory_bytes()) / (1024.0 * 1024.0);

    // The key column as wide as the longest key, the structure's figures' or the fixed rows' ("scene").
    std::size_t key_width = std::string_view("scene").size();
    for (const AccelFigure& figure : stats.figures)
        key_width = std::max(key_width, figure.key.size());
    fmt::print("{:<{}} {} ({} primitives), load {:.1f} ms\n", "scene", key_width, options.scene_file,
               primitives, prepared.load_ms);
    fmt::print("{:<{}} {}\n", "accel", key_width, accel.name());
    fmt::print("{:<{}} {:.1f} ms ({:.2f} Mprims/s)\n", "build", key_width, prepared.build_ms,
               prepared.build_ms > 0.0 ? static_cast<double>(primitives) / (prepared.build_ms * 1e3) : 0.0);
    // The structure's own figures, as it names and explains them.
    for (const AccelFigure& figure : stats.figures)
        fmt::print("{:<{}} {:>12}  {}\n", figure.key, key_width, figure_text(figure), figure.help);
    fmt::print("{:<{}} {:.3f} MB", "memory", key_width, memory_mb);
    for (const auto& [array, bytes] : stats.memory_by_array) {
        fmt::print(", {} {:.3f} MB", array, static_cast<double>(bytes) / (1024.0 * 1024.0));
    }
    fmt::print("\n");

    RayCost cost;
    if (options.rays) {
        const auto [width, height] = parse_size(options.size);
        cost = trace_view(accel, prepared.world.scene(), width, height);
        const double rays = static_cast<double>(cost.rays);
        fmt::print("{:<{}} {}x{}, {:.1f}% hits, {:.2f} nodes/ray, {:.2f} prims/ray (one thread, counting)\n",
                   "view", key_width, width, height, 100.0 * static_cast<double>(cost.hits) / rays,
                   static_cast<double>(cost.counters.nodes_visited) / rays,
                   static_cast<double>(cost.counters.prims_tested) / rays);
    }

    if (!options.json_file.empty()) {
        std::string memory_json;
        for (const auto& [array, bytes] : stats.memory_by_array) {
            memory_json += fmt::format("{}\"{}\": {}", memory_json.empty() ? "" : ", ", array, bytes);
        }
        std::string json =
            fmt::format("{{\"scene\": \"{}\", \"accel\": \"{}\", \"primitives\": {}, \"build_ms\": {:.3f}",
                        options.scene_file, accel.name(), primitives, prepared.build_ms);
        for (const AccelFigure& figure : stats.figures)
            json += fmt::format(", \"{}\": {}", figure.key, figure_json(figure));
        json += fmt::format(", \"memory_bytes\": {}, \"memory_by_array\": {{{}}}", accel.memory_bytes(),
                            memory_json);
        if (options.rays) {
            const double rays = static_cast<double>(cost.rays);
            json += fmt::format(
                ", \"rays\": {}, \"hit_fraction\": {:.6f}, \"nodes_per_ray\": {:.4f}, "
                "\"prims_per_ray\": {:.4f}",
                cost.rays, static_cast<double>(cost.hits) / rays,
                static_cast<double>(cost.counters.nodes_visited) / rays,
                static_cast<double>(cost.counters.prims_tested) / rays);
        }
        json += "}\n";
        try {
            fmt::output_file(options.json_file).print("{}", json);
        } catch (const std::system_error& error) {
            throw InputError(options.json_file + ": " + error.what());
        }
    }
}

}  // namespace

void add_stats_command(CLI::App& app) {
    auto options = std::make_shared<StatsOptions>();
    CLI::App* command = app.add_subcommand("stats", "Build a structure and print its statistics");
    command->add_option("scene", options->scene_file, "Mesh or scene file, or a .plo octree (lancer convert)")
        ->required();
    options->accel.add_options(*command);
    command->add_option("--json", options->json_file, "Also write the statistics as JSON");
    command->add_flag("--rays", options->rays,
                      "Trace the canonical view and report nodes and primitives per ray");
    command->add_option("--size", options->size, "Image size of the --rays view")->capture_default_str();
    command->callback([options] { run(*options); });
}

}  // namespace lancer::cli
