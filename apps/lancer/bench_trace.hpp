// The paths lancer bench times: the canonical view in 8x8 pixel tiles, one RayPacket each, tiles in
// scanline order over the caller's threads; and the secondary views, made once per mesh from its hits and
// traced from an array in memory.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "bench_report.hpp"
#include "lancer/accel.hpp"
#include "lancer/camera.hpp"

namespace lancer::cli {

// One frame as VIEWS.md times it: generate every ray from the camera, trace it, store its closest hit at its
// pixel. One task per row of tiles, on the threads of the run_with_threads the caller runs in. An Embree
// row's task sets flush-to-zero once, as Embree's manual and tutorials do (lancer/denormals.hpp); lancer's
// structures run in the IEEE mode.
void trace_frame(const Accel& accel, const PinholeCamera& camera, std::vector<Hit>& hits);

// One view of one mesh: its rays (in pixel order for the primary view, as its hits are stored) and the
// first structure's answers, which every other structure must give. The shadow view's reference is the
// first structure's closest hits: a ray is occluded when it has one.
struct ViewRays {
    BenchView view;
    std::vector<Ray> rays;
    std::vector<Hit> reference;
    std::string reference_name;
};

// One structure's answers on a view through the path that is timed, with its traversal counts.
struct ViewAnswers {
    std::vector<Hit> hits;
    std::vector<std::uint8_t> occluded;
    TraversalCounters counters;
    std::size_t hit_count = 0;  // rays that hit (primary, diffuse) or are occluded (shadow)
};

// One structure's answers on a view through the timed path, counting.
[[nodiscard]] ViewAnswers answer_view(const Accel& accel, const ViewRays& view, const PinholeCamera& camera);

// The canonical view's rays, and the secondary sets asked for, made from lancer's closest hits on it (any
// structure's, bit for bit: the binary BVH's, whose build is quick).
[[nodiscard]] std::vector<ViewRays> make_views(const std::vector<BenchView>& wanted, const Geometry& geometry,
                                               const PinholeCamera& camera, bool watertight);

}  // namespace lancer::cli
