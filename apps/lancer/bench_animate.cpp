#include "bench_animate.hpp"

#include <fmt/core.h>
#include <fmt/os.h>

#include <algorithm>
#include <memory>
#include <optional>

#include "bench_trace.hpp"
#include "common.hpp"
#include "lancer/agreement.hpp"
#include "lancer/animate.hpp"
#include "lancer/camera.hpp"
#include "lancer/parallel.hpp"
#include "lancer/world.hpp"

namespace lancer::cli {
namespace {

// The structure's SAH cost, 0 for one without (Embree, the grid on a flat box).
double sah_cost_in(const AccelStats& stats) {
    const AccelFigure* cost = stats.find("sah_cost");
    return cost != nullptr ? cost->value : 0.0;
}

// One row of the table: a structure updated frame after frame, or built afresh on every frame.
struct AnimatedRow {
    std::string accel;
    bool rebuild = false;
    BuildOptions options;
    std::optional<World> world;
    std::vector<double> update_ms, structure_ms, trace_ms, sah_ratio;

    [[nodiscard]] std::string label() const { return accel + (rebuild ? " rebuild" : " update"); }
};

// One frame of one row, for --json.
struct AnimatedRecord {
    std::string mesh, row, method;
    int threads = 0, frame = 0;
    // update_ms: the whole update or rebuild (World's checks, copy and flattening with it); structure_ms:
    // the structure's own refit or build. The SAH ratios, 0 for a structure without an SAH cost (Embree).
    double update_ms = 0.0, structure_ms = 0.0, trace_ms = 0.0, mrays = 0.0, sah_ratio = 0.0,
           sah_vs_fresh = 0.0;
};

double median(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    return values.empty() ? 0.0 : values[values.size() / 2];
}

// The rows of one structure: its update and its rebuild. An Embree structure's update row uses Embree's
// refit quality (a dynamic scene of LOW quality whose geometry is refitted, as Embree's dynamic_scene
// tutorial sets it up); its rebuild row the quality --set gives (HIGH by default).
std::vector<AnimatedRow> rows_of(const std::string& accel, const AnimatedBenchOptions& options) {
    const BuildOptions chosen = AccelChoice{accel, options.watertight, options.settings}.build_options();
    BuildOptions update = chosen;
    if (accel.starts_with("embree")) set_build_option(update, "embree.quality=refit");
    std::vector<AnimatedRow> rows;
    rows.push_back({accel, false, update, std::nullopt, {}, {}, {}, {}});
    rows.push_back({accel, true, chosen, std::nullopt, {}, {}, {}, {}});
    return rows;
}

// A ratio, or n/a where it is 0 (a structure without an SAH cost).
std::string ratio_text(double ratio) {
    return ratio > 0.0 ? fmt::format("{:.3f}", ratio) : std::string("n/a");
}

std::string method_name(UpdateMethod method) {
    return method == UpdateMethod::Refit ? "refit" : "rebuild";
}

void write_json(const std::string& file, const std::vector<AnimatedRecord>& records) {
    std::string json = "[\n";
    for (std::size_t i = 0; i < records.size(); ++i) {
        const AnimatedRecord& r = records[i];
        json += fmt::format(
            "  {{\"mesh\": \"{}\", \"row\": \"{}\", \"method\": \"{}\", \"threads\": {}, \"frame\": {}, "
            "\"update_ms\": {:.4f}, \"structure_ms\": {:.4f}, \"trace_ms\": {:.4f}, \"mrays\": {:.4f}, "
            "\"sah_ratio\": {:.5f}, "
            "\"sah_vs_fresh\": {:.5f}}}{}\n",
            r.mesh, r.row, r.method, r.threads, r.frame, r.update_ms, r.structure_ms, r.trace_ms, r.mrays,
            r.sah_ratio, r.sah_vs_fresh, i + 1 < records.size() ? "," : "");
    }
    json += "]\n";
    try {
        fmt::output_file(file).print("{}", json);
    } catch (const std::system_error& error) {
        throw InputError(file + ": " + error.what());
    }
}

}  // namespace

void run_animated_bench(const std::vector<AnimatedBenchMesh>& meshes, const AnimatedBenchOptions& options) {
    // Unknown names before anything is built.
    for (const std::string& accel : options.accels) {
        try {
            static_cast<void>(make_accel(accel));
        } catch (const std::invalid_argument& error) {
            throw InputError(std::string("--accel: ") + error.what());
        }
    }
    fmt::print(
        "animation: a sine wave along x lifting y by 5% of the largest extent, one wavelength across\n"
        "the box, {} frames per period (lancer/animate.hpp); per frame the update (or rebuild) and one\n"
        "{}x{} canonical view of the rest pose's box\n",
        options.frames, options.size, options.size);
    fmt::print("{:<16} {:>3} {:>5} {:<20} {:<8} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9}\n", "mesh", "thr",
               "frame", "row", "method", "update ms", "struct ms", "trace ms", "Mrays/s", "SAH ratio",
               "vs fresh");
    std::vector<AnimatedRecord> records;
    bool agreement_failed = false;
    for (const AnimatedBenchMesh& mesh : meshes) {
        const Scene& rest = *mesh.scene;
        const SineWave wave{rest.bounds(), options.frames};
        const PinholeCamera camera(canonical_view(rest.bounds(), options.size, options.size));
        const double ray_count = static_cast<double>(options.size) * options.size;
        const std::vector<Ray> rays = camera.pixel_centre_rays(0, 0, camera.width(), camera.height());
        for (const int threads : options.thread_counts) {
            // One arena per thread count, so that the timed builds, updates and traces below all run in it.
            run_with_threads(threads, [&] {
                std::vector<AnimatedRow> rows;
                for (const std::string& accel : options.accels) {
                    for (AnimatedRow& row : rows_of(accel, options)) {
                        row.world.emplace(rest, row.accel, row.options);
                        rows.push_back(std::move(row));
                    }
                }
                std::vector<Hit> reference(rays.size()), hits(rays.size());
                for (int frame = 1; frame <= options.frames; ++frame) {
                    const std::vector<std::vector<Vec3f>> moved = deformed_meshes(rest, wave, frame);
                    std::vector<MeshVertices> moves;
                    for (std::size_t m = 0; m < moved.size(); ++m)
                        moves.push_back({m, moved[m]});
                    std::vector<AnimatedRecord> frame_records;
                    std::vector<double> sah_costs;  // each row's structure on this frame
                    for (std::size_t r = 0; r < rows.size(); ++r) {
                        AnimatedRow& row = rows[r];
                        UpdateReport report;
                        double update_ms = 0.0;
                        if (row.rebuild) {
                            Scene moved_scene = rest;
                            for (std::size_t m = 0; m < moved.size(); ++m)
                                moved_scene.meshes[m].positions = moved[m];
                            row.world.reset();  // the old structure's memory is freed before the clock starts
                            const Stopwatch watch;
                            row.world.emplace(std::move(moved_scene), row.accel, row.options);
                            update_ms = watch.elapsed_ms();
                        } else {
                            const Stopwatch watch;
                            report = row.world->update_vertices(moves);
                            update_ms = watch.elapsed_ms();
                        }
                        const Stopwatch trace_watch;
                        trace_frame(row.world->accel(), camera, r == 0 ? reference : hits);
                        const double trace_ms = trace_watch.elapsed_ms();
                        if (r > 0) {
                            const Agreement agreement = compare_hits(rays, reference, hits);
                            // Embree is a peer with its own triangle test: its differences are shown, not
                            // failed.
                            const bool peer =
                                row.accel.starts_with("embree") || rows[0].accel.starts_with("embree");
                            if (agreement.mismatches > 0) {
                                fmt::print(peer ? stdout : stderr, "bench: {} {} {} on {}, frame {}: {}\n",
                                           row.label(), peer ? "differs from" : "disagrees with",
                                           rows[0].label(), mesh.name, frame, agreement.summary());
                                agreement_failed = agreement_failed || !peer;
                            }
                        }
                        // Once a frame: a tree's stats walk the whole tree.
                        const AccelStats stats = row.world->accel().stats();
                        sah_costs.push_back(sah_cost_in(stats));
                        const double structure_ms = row.rebuild ? stats.build_ms : report.structure_ms;
                        row.update_ms.push_back(update_ms);
                        row.structure_ms.push_back(structure_ms);
                        row.trace_ms.push_back(trace_ms);
                        row.sah_ratio.push_back(sah_costs.back() > 0.0 ? report.sah_ratio : 0.0);
                        frame_records.push_back({mesh.name, row.label(),
                                                 row.rebuild ? "build" : method_name(report.method), threads,
                                                 frame, update_ms, structure_ms, trace_ms,
                                                 ray_count / (trace_ms * 1e3), row.sah_ratio.back(), 0.0});
                    }
                    // An updated tree's SAH cost over the one its rebuild row built afresh on the same frame.
                    for (std::size_t r = 0; r + 1 < rows.size(); ++r) {
                        if (rows[r].rebuild || !rows[r + 1].rebuild || rows[r].accel != rows[r + 1].accel)
                            continue;
                        if (sah_costs[r + 1] > 0.0)
                            frame_records[r].sah_vs_fresh = sah_costs[r] / sah_costs[r + 1];
                    }
                    for (const AnimatedRecord& record : frame_records) {
                        fmt::print(
                            "{:<16} {:>3} {:>5} {:<20} {:<8} {:>10.2f} {:>9.2f} {:>9.2f} {:>9.2f} {:>9} "
                            "{:>9}\n",
                            record.mesh, record.threads, record.frame, record.row, record.method,
                            record.update_ms, record.structure_ms, record.trace_ms, record.mrays,
                            ratio_text(record.sah_ratio), ratio_text(record.sah_vs_fresh));
                        records.push_back(record);
                    }
                    std::fflush(stdout);
                }
                fmt::print("{:<16} {:>3} medians over {} frames:\n", mesh.name, threads, options.frames);
                for (const AnimatedRow& row : rows) {
                    std::vector<double> frame_ms;
                    for (std::size_t f = 0; f < row.update_ms.size(); ++f)
                        frame_ms.push_back(row.update_ms[f] + row.trace_ms[f]);
                    fmt::print(
                        "  {:<20} update {:>8.2f} ms (structure {:>8.2f}), trace {:>8.2f} ms, update + trace "
                        "{:>8.2f} "
                        "ms, SAH ratio {}\n",
                        row.label(), median(row.update_ms), median(row.structure_ms), median(row.trace_ms),
                        median(frame_ms), ratio_text(median(row.sah_ratio)));
                }
            });
        }
    }
    if (!options.json_file.empty()) write_json(options.json_file, records);
    if (agreement_failed)
        throw CheckFailure("bench: structures disagree (see above); figures not trustworthy");
}

}  // namespace lancer::cli
