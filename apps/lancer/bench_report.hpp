// lancer bench's report: a row per mesh, view, structure and thread count, written as JSON and as an SVG bar
// chart.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace lancer::cli {

// The canonical view's camera rays, or one of the secondary sets made from its hits.
enum class BenchView { Primary, Diffuse, Shadow };

[[nodiscard]] std::string_view view_name(BenchView view);

// One row of the bench: a structure on a mesh, a view and a thread count.
struct BenchRecord {
    std::string mesh;
    BenchView view = BenchView::Primary;
    std::size_t triangles = 0;
    std::string accel;
    int threads = 0;
    double build_ms = 0.0;
    std::size_t memory_bytes = 0;
    std::size_t geometry_bytes = 0;
    double mrays_median = 0.0, mrays_min = 0.0, mrays_max = 0.0;
    double hit_fraction = 0.0;
    double nodes_per_ray = 0.0, prims_per_ray = 0.0;
    bool counted = false;        // false for structures that expose no traversal counts (Embree)
    std::size_t mismatches = 0;  // rays answered otherwise than by the first structure (Embree rows only)
};

// Throw InputError when the file cannot be written.
void write_bench_json(const std::string& file, const std::vector<BenchRecord>& records);
// Horizontal bars, one group per mesh, one bar per structure and thread count, labelled with the value.
void write_bench_svg(const std::string& file, const std::vector<BenchRecord>& records);

}  // namespace lancer::cli
