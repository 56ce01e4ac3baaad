// A leaf's triangles on the GPU, tested by the triangle tests of core/intersect.hpp, which are host-device:
// with no product fused but where they say so (g++ -ffp-contract=off, nvcc --fmad=false) and IEEE division
// (nvcc's default -prec-div=true) they return the CPU's t, u and v bit for bit. Spheres are not ported: the
// GPU path traces triangle meshes (docs/cuda.md).
#pragma once

#include "core/intersect.hpp"
#include "cuda/read_only_cache.hpp"
#include "lancer/scene.hpp"

namespace lancer::gpu {

// One triangle record (TriangleRef or PluckerPrimitive: a triangle and its global index) tested within
// [tnear, the closest hit so far]; true when it becomes the closest, ties to the smaller index (closer() of
// lancer/ray.hpp).
template <class TriangleTestT, class Record>
LANCER_HOST_DEVICE bool intersect_record(const Record* address,
                                         const typename TriangleTestT::RayData& triangle_ray, const Ray& ray,
                                         Hit& best) {
    const Record record = read_only_record(address);
    const float tfar = best.prim >= 0 ? best.t : ray.tfar;
    TriangleHit candidate;
    const auto prim = static_cast<std::int32_t>(record.prim);
    if (!TriangleTestT::intersect(triangle_ray, record.triangle, ray.tnear, tfar, candidate) ||
        !closer(candidate.t, prim, best))
        return false;
    best = {candidate.t, prim, candidate.u, candidate.v};
    return true;
}

// A leaf's `count` triangle records from `records`, the closest wins. kAnyHit (occlusion) stops at the first
// hit, which then need not be the closest. Returns whether `best` holds a hit.
template <class TriangleTestT, bool kAnyHit = false, class Record>
LANCER_HOST_DEVICE bool intersect_leaf(const Record* records, std::uint32_t count,
                                       const typename TriangleTestT::RayData& triangle_ray, const Ray& ray,
                                       Hit& best) {
    for (std::uint32_t r = 0; r < count; ++r) {
        if (intersect_record<TriangleTestT>(records + r, triangle_ray, ray, best) && kAnyHit) return true;
    }
    return best.prim >= 0;
}

}  // namespace lancer::gpu
