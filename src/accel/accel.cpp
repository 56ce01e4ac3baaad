// The non-virtual half of the Accel interface: the checks and the ray conditioning every structure shares
// (src/core/ray_conditioning.hpp), done once per batch around the structure's own batch loop.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "accel/build_util.hpp"
#include "accel/packet_batch.hpp"
#include "core/checked_points.hpp"
#include "core/parallel.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/accel.hpp"

namespace lancer {

namespace {

void check_batch(std::size_t ray_count, std::size_t answer_count) {
    if (ray_count != answer_count) throw std::invalid_argument("Accel: one answer slot per ray expected");
}

// Conditions the batch, hands it to `trace` (one of the closest-hit batch methods), maps the hits back.
template <class Trace>
void intersect_conditioned(std::span<const Ray> rays, std::span<Hit> hits, const Box3f& bounds,
                           int scene_exponent, Trace&& trace) {
    check_batch(rays.size(), hits.size());
    const ConditionedRays conditioned = condition_rays(rays, bounds, scene_exponent);
    trace(conditioned.rays.empty() ? rays : std::span<const Ray>(conditioned.rays));
    restore_hits(conditioned, rays, hits);
}

}  // namespace

Box3f Accel::checked_bounds(const Geometry& geometry) {
    static_assert(sizeof(Triangle) == 9 * sizeof(float) && std::is_standard_layout_v<Triangle>);
    const CheckedPoints triangles = check_points(
        {reinterpret_cast<const float*>(geometry.triangles.data()), 9 * geometry.triangles.size()}, 3);
    if (triangles.first_outside != CheckedPoints::kNone) {
        throw std::invalid_argument("Accel: triangle " + std::to_string(triangles.first_outside) +
                                    " has a vertex outside the coordinate domain [-2^60, 2^60]");
    }
    Box3f bounds = triangles.box;
    for (std::size_t i = 0; i < geometry.spheres.size(); ++i) {
        const Sphere& sphere = geometry.spheres[i];
        if (!(sphere.radius > 0.0f)) continue;  // never hit (docs/numerical-contract.md, "Spheres")
        const Box3f box = sphere.bounds();
        if (!in_coordinate_domain(box.lo) || !in_coordinate_domain(box.hi)) {
            throw std::invalid_argument("Accel: sphere " + std::to_string(i) +
                                        " reaches outside the coordinate domain [-2^60, 2^60]");
        }
        bounds.extend(box);
    }
    return bounds;
}

void Accel::accept_geometry(const Geometry& geometry) {
    bounds_ = checked_bounds(geometry);
    triangle_count_ = geometry.triangles.size();
    sphere_count_ = geometry.spheres.size();
    scale_exponent_ = scene_scale_exponent(bounds_);
    make_built_geometry(geometry);
}

void Accel::make_built_geometry(const Geometry& geometry) {
    ++geometry_version_;
    if (scale_exponent_ == 0) {
        scaled_triangles_ = {}, scaled_spheres_ = {};
        built_geometry_ = geometry;
        built_bounds_ = bounds_;
        return;
    }
    built_bounds_ = scale_geometry(geometry, scale_exponent_, scaled_triangles_, scaled_spheres_);
    built_geometry_ = {scaled_triangles_, scaled_spheres_};
}

void Accel::build(const Geometry& geometry, const BuildOptions& options) {
    accept_geometry(geometry);
    build_structure(built_geometry_, options);
}

UpdateReport Accel::update(const Geometry& geometry) {
    const auto start = std::chrono::steady_clock::now();
    if (geometry.triangles.size() != triangle_count_ || geometry.spheres.size() != sphere_count_) {
        throw std::invalid_argument("Accel::update: " + std::to_string(geometry.triangles.size()) +
                                    " triangles and " + std::to_string(geometry.spheres.size()) +
                                    " spheres, expected the " + std::to_string(triangle_count_) + " and " +
                                    std::to_string(sphere_count_) + " it was built on");
    }
    UpdateReport report = update_within(geometry, checked_bounds(geometry));
    report.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return report;
}

UpdateReport Accel::update_within(const Geometry& geometry, const Box3f& bounds) {
    const auto start = std::chrono::steady_clock::now();
    // The box first: a structure that rebuilds reads it (embree's scale, the octrees' root cube).
    bounds_ = bounds;
    // A scene that moved into another scale is seen at the new one: every structure's update derives its
    // boxes or cells from the geometry it is given (a refit recomputes every box), so none keeps a size of
    // the old scale.
    scale_exponent_ = scene_scale_exponent(bounds);
    make_built_geometry(geometry);
    UpdateReport report = update_structure(built_geometry_);
    report.structure_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return report;
}

void Accel::build_held(Accel& held, const Geometry& geometry, const BuildOptions& options) const {
    held.bounds_ = built_bounds_;
    held.triangle_count_ = geometry.triangles.size();
    held.sphere_count_ = geometry.spheres.size();
    held.scale_exponent_ = 0;
    held.make_built_geometry(geometry);
    held.build_structure(held.built_geometry_, options);
}

UpdateReport Accel::update_held(Accel& held, const Geometry& geometry) const {
    // The held structure was built on this one's built geometry, at scale 1.
    held.bounds_ = built_bounds_, held.built_bounds_ = built_bounds_;
    held.built_geometry_ = geometry;
    return held.update_structure(geometry);
}

void Accel::intersect(std::span<const Ray> rays, std::span<Hit> hits, TraversalCounters* counters) const {
    intersect_conditioned(rays, hits, bounds_, scale_exponent_,
                          [&](std::span<const Ray> batch) { intersect_batch(batch, hits, counters); });
}

void Accel::intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits,
                               TraversalCounters* counters) const {
    intersect_conditioned(rays, hits, bounds_, scale_exponent_, [&](std::span<const Ray> batch) {
        intersect_coherent_batch(batch, hits, counters);
    });
}

void Accel::intersect_packet(const RayPacket& rays, HitPacket& hits, TraversalCounters* counters) const {
    if (rays.size < 0 || rays.size > RayPacket::kMaxSize) {
        throw std::invalid_argument("Accel::intersect_packet: packet size " + std::to_string(rays.size) +
                                    ", expected 0 to " + std::to_string(RayPacket::kMaxSize));
    }
    if (scale_exponent_ == 0 && !any_may_need_conditioning(rays, FarOriginFrame(bounds_))) {
        intersect_packet_rays(rays, hits, counters);
        return;
    }
    // A packet with a ray to condition (rare: a far origin, an extreme direction, a scene scaled outside the
    // ordinary range) takes the batch path.
    trace_packet_as_batch(rays, hits, [&](std::span<const Ray> batch, std::span<Hit> batch_hits) {
        intersect_coherent(batch, batch_hits, counters);
    });
}

void Accel::intersect_packet_rays(const RayPacket& rays, HitPacket& hits, TraversalCounters* counters) const {
    trace_packet_as_batch(rays, hits, [&](std::span<const Ray> batch, std::span<Hit> batch_hits) {
        intersect_coherent_batch(batch, batch_hits, counters);
    });
}

void Accel::occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                     TraversalCounters* counters) const {
    check_batch(rays.size(), occluded.size());
    const ConditionedRays conditioned = condition_rays(rays, bounds_, scale_exponent_);
    occluded_batch(conditioned.rays.empty() ? rays : std::span<const Ray>(conditioned.rays), occluded,
                   counters);
}

namespace {

// Rays per task of intersect_parallel and occluded_parallel (lancer/accel.hpp), the size of
// bench/embree_reference's arrays too.
constexpr std::size_t kRayChunk = 4096;

}  // namespace

const AccelFigure* AccelStats::find(std::string_view key) const {
    const auto figure = std::find_if(figures.begin(), figures.end(),
                                     [&](const AccelFigure& candidate) { return candidate.key == key; });
    return figure == figures.end() ? nullptr : &*figure;
}

namespace {

const AccelFigure& required_figure(const AccelStats& stats, std::string_view key) {
    const AccelFigure* figure = stats.find(key);
    if (figure == nullptr) throw std::out_of_range("the structure has no figure '" + std::string(key) + "'");
    return *figure;
}

}  // namespace

double AccelStats::value(std::string_view key) const {
    return required_figure(*this, key).value;
}

std::size_t AccelStats::count(std::string_view key) const {
    const AccelFigure& figure = required_figure(*this, key);
    if (!figure.whole) throw std::invalid_argument("the figure '" + std::string(key) + "' is not a count");
    return static_cast<std::size_t>(figure.value);
}

void intersect_parallel(const Accel& accel, std::span<const Ray> rays, std::span<Hit> hits, int threads) {
    check_batch(rays.size(), hits.size());
    parallel::with_threads(threads, [&] {
        parallel::for_each_block(rays.size(), kRayChunk, [&](std::size_t from, std::size_t to) {
            accel.intersect(rays.subspan(from, to - from), hits.subspan(from, to - from));
        });
    });
}

void occluded_parallel(const Accel& accel, std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                       int threads) {
    check_batch(rays.size(), occluded.size());
    parallel::with_threads(threads, [&] {
        parallel::for_each_block(rays.size(), kRayChunk, [&](std::size_t from, std::size_t to) {
            accel.occluded(rays.subspan(from, to - from), occluded.subspan(from, to - from));
        });
    });
}

}  // namespace lancer
