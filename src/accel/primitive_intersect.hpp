// What every structure does at a leaf: test one primitive of the global numbering against a ray, and the
// once-per-batch dispatch of the policies that shape the hot loop, never a flag tested inside it.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>

#include "core/intersect.hpp"
#include "lancer/accel.hpp"

namespace lancer {

// A ray with what its triangle test precomputes from it (the watertight shear, for instance).
template <class TriangleTestT>
struct PreparedRay {
    Ray ray;
    typename TriangleTestT::RayData triangle_data;

    explicit PreparedRay(const Ray& r) : ray(r), triangle_data(r) {}

    // The same ray from `origin`: what the test precomputes depends on the direction alone, so rays that
    // share it are prepared once (GeometryQueries::count_crossings).
    void set_origin(const Vec3f& origin) { ray.origin = origin, triangle_data.origin = origin; }
};

// Tests primitive `prim` (triangles first, then spheres) against the ray within [ray.tnear, best.t] for a
// closest hit; on a closer hit (ties by index, see closer()) overwrites `best` and returns true.
template <class TriangleTestT>
inline bool intersect_primitive(const Geometry& geometry, std::uint32_t prim,
                                const PreparedRay<TriangleTestT>& prepared, Hit& best) {
    TriangleHit candidate;
    const float tfar = best.hit() ? best.t : prepared.ray.tfar;
    bool found;
    if (prim < geometry.triangles.size()) {
        found = TriangleTestT::intersect(prepared.triangle_data, geometry.triangles[prim], prepared.ray.tnear,
                                         tfar, candidate);
    } else {
        found = intersect_sphere(prepared.ray, geometry.spheres[prim - geometry.triangles.size()],
                                 prepared.ray.tnear, tfar, candidate);
    }
    if (!found || !closer(candidate.t, static_cast<std::int32_t>(prim), best)) return false;
    best = {candidate.t, static_cast<std::int32_t>(prim), candidate.u, candidate.v};
    return true;
}

// Any hit in [tnear, tfar].
template <class TriangleTestT>
inline bool occludes(const Geometry& geometry, std::uint32_t prim,
                     const PreparedRay<TriangleTestT>& prepared) {
    TriangleHit candidate;
    if (prim < geometry.triangles.size()) {
        return TriangleTestT::intersect(prepared.triangle_data, geometry.triangles[prim], prepared.ray.tnear,
                                        prepared.ray.tfar, candidate);
    }
    return intersect_sphere(prepared.ray, geometry.spheres[prim - geometry.triangles.size()],
                            prepared.ray.tnear, prepared.ray.tfar, candidate);
}

// Calls body.template operator()<TriangleTestT, kCount>() with the policies chosen at run time, once.
template <class Body>
inline void dispatch_policies(TriangleTest test, bool count, Body&& body) {
    if (test == TriangleTest::Watertight) {
        count ? body.template operator()<Watertight, true>() : body.template operator()<Watertight, false>();
    } else {
        count ? body.template operator()<MollerTrumbore, true>()
              : body.template operator()<MollerTrumbore, false>();
    }
}

// The batch loops every structure shares: the policies dispatched once per batch, invalid rays (is_valid)
// answered as misses without any traversal, counts summed in a local (the hot loop never writes through the
// caller's pointer) and added once. For one valid ray,
//   closest.template operator()<TriangleTestT, kCount>(prepared, best, counts) improves the Hit `best`;
//   any.template operator()<TriangleTestT, kCount>(prepared, counts) returns whether anything is hit.
template <class ClosestOne>
void intersect_each(TriangleTest test, std::span<const Ray> rays, std::span<Hit> hits,
                    TraversalCounters* counters, ClosestOne&& closest) {
    dispatch_policies(test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            Hit best;  // a local, not hits[i]: it stays in registers
            if (is_valid(rays[i])) {
                closest.template operator()<TriangleTestT, kCount>(PreparedRay<TriangleTestT>(rays[i]), best,
                                                                   counts);
            }
            hits[i] = best;
        }
        if constexpr (kCount) {
            counts.rays = rays.size();
            *counters += counts;
        }
    });
}

template <class AnyOne>
void occluded_each(TriangleTest test, std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                   TraversalCounters* counters, AnyOne&& any) {
    dispatch_policies(test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            occluded[i] = is_valid(rays[i]) && any.template operator()<TriangleTestT, kCount>(
                                                   PreparedRay<TriangleTestT>(rays[i]), counts);
        }
        if constexpr (kCount) {
            counts.rays = rays.size();
            *counters += counts;
        }
    });
}

// The packet loop of the packet structures: the batch cut into packets of kPacketSize consecutive rays.
// trace_packet(packet_rays, packet_answers) traces one and returns false when its rays cannot go together;
// `single`, the structure's single-ray sibling, then answers them one at a time. Answer: Hit (closest hit)
// or std::uint8_t (occlusion, kAnyHit).
template <std::size_t kPacketSize, bool kAnyHit, bool kCount, class Answer, class TracePacket>
void for_each_packet(std::span<const Ray> rays, std::span<Answer> answers, const Accel& single,
                     TraversalCounters& counts, TracePacket&& trace_packet) {
    for (std::size_t first = 0; first < rays.size(); first += kPacketSize) {
        const std::size_t count = std::min(kPacketSize, rays.size() - first);
        const std::span<const Ray> packet_rays = rays.subspan(first, count);
        const std::span<Answer> packet_answers = answers.subspan(first, count);
        if (trace_packet(packet_rays, packet_answers)) {
            if constexpr (kCount) counts.rays += count;
        } else if constexpr (kAnyHit) {
            single.occluded(packet_rays, packet_answers, kCount ? &counts : nullptr);
        } else {
            single.intersect(packet_rays, packet_answers, kCount ? &counts : nullptr);
        }
    }
}

}  // namespace lancer
