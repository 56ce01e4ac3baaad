// The non-virtual half of the Accel interface: the checks and the far-ray handling every structure shares,
// done once per batch around the structure's own batch loop.
#include <string>
#include <vector>

#include "core/far_origin.hpp"
#include "lancer/accel.hpp"

namespace lancer {

namespace {

void check_batch(std::size_t ray_count, std::size_t answer_count) {
    if (ray_count != answer_count) throw std::invalid_argument("Accel: one answer slot per ray expected");
}

// The far rays of a batch moved near the scene (core/far_origin.hpp), with their shifts; empty when the
// batch has none, the common case, which then costs one pass over the origins.
struct MovedBatch {
    std::vector<Ray> rays;
    std::vector<double> shifts;  // per ray, 0 for the rays left as they were
};

MovedBatch move_far_rays(std::span<const Ray> rays, const Box3f& bounds) {
    const FarOriginFrame frame(bounds);
    MovedBatch moved;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (!is_valid(rays[i]) || !frame.is_far(rays[i])) continue;
        const std::optional<FarOriginFrame::Moved> near = frame.move_near(rays[i]);
        if (!near) continue;
        if (moved.rays.empty())
            moved.rays.assign(rays.begin(), rays.end()), moved.shifts.assign(rays.size(), 0.0);
        moved.rays[i] = near->ray;
        moved.shifts[i] = near->shift;
    }
    return moved;
}

}  // namespace

void Accel::accept_geometry(const Geometry& geometry) {
    Box3f bounds;
    for (std::size_t i = 0; i < geometry.triangles.size(); ++i) {
        const Triangle& triangle = geometry.triangles[i];
        if (!in_coordinate_domain(triangle.v0) || !in_coordinate_domain(triangle.v1) ||
            !in_coordinate_domain(triangle.v2)) {
            throw std::invalid_argument("Accel::build: triangle " + std::to_string(i) +
                                        " has a vertex outside the coordinate domain [-2^60, 2^60]");
        }
        bounds.extend(triangle.bounds());
    }
    for (std::size_t i = 0; i < geometry.spheres.size(); ++i) {
        const Sphere& sphere = geometry.spheres[i];
        if (!(sphere.radius > 0.0f)) continue;  // never hit (docs/numerical-contract.md, "Spheres")
        const Box3f box = sphere.bounds();
        if (!in_coordinate_domain(box.lo) || !in_coordinate_domain(box.hi)) {
            throw std::invalid_argument("Accel::build: sphere " + std::to_string(i) +
                                        " reaches outside the coordinate domain [-2^60, 2^60]");
        }
        bounds.extend(box);
    }
    bounds_ = bounds;
}

void Accel::build(const Geometry& geometry, const BuildOptions& options) {
    accept_geometry(geometry);
    build_structure(geometry, options);
}

void Accel::intersect(std::span<const Ray> rays, std::span<Hit> hits, TraversalCounters* counters) const {
    check_batch(rays.size(), hits.size());
    const MovedBatch moved = move_far_rays(rays, bounds_);
    if (moved.rays.empty()) {
        intersect_batch(rays, hits, counters);
        return;
    }
    intersect_batch(moved.rays, hits, counters);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (moved.shifts[i] != 0.0 && hits[i].hit())
            hits[i].t = FarOriginFrame::restore_t(hits[i].t, moved.shifts[i], rays[i]);
    }
}

void Accel::occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                     TraversalCounters* counters) const {
    check_batch(rays.size(), occluded.size());
    const MovedBatch moved = move_far_rays(rays, bounds_);
    occluded_batch(moved.rays.empty() ? rays : std::span<const Ray>(moved.rays), occluded, counters);
}

}  // namespace lancer
