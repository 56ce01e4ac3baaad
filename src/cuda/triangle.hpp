// A leaf's triangles on the GPU, tested by the triangle tests of core/intersect.hpp, which are host-device:
// with unfused products (g++ -ffp-contract=off, nvcc --fmad=false) and IEEE division (nvcc's default
// -prec-div=true) they return the CPU's t, u and v bit for bit. Spheres are not ported: the GPU path traces
// triangle meshes (docs/cuda.md).
#pragma once

#include "core/intersect.hpp"
#include "cuda/read_only_cache.hpp"
#include "lancer/scene.hpp"

namespace lancer::gpu {

// A triangle test's first pass on the GPU (Test: MollerTrumbore or Watertight): the float test alone,
// its rare double and exact paths left out, so that the traversal keeps the registers it needs without them
// (docs/cuda.md, "Two passes"). A triangle it cannot decide marks the ray `undecided`; settled() then
// makes the ray's answer kUndecided and the kernel traces that ray again with Test. Every other answer is
// the one Test gives: the two differ only on the triangles deferred.
template <class Test>
struct FirstPassRayData : Test::RayData {
    using Test::RayData::RayData;
    mutable bool undecided = false;
};
template <class Test>
struct FirstPass {
    using RayData = FirstPassRayData<Test>;
    [[nodiscard]] LANCER_HOST_DEVICE static bool intersect(const RayData& ray, const Triangle& tri,
                                                           float tnear, float tfar, TriangleHit& out) {
        return Test::template intersect_or_defer<true>(ray, tri, tnear, tfar, out, ray.undecided);
    }
};

// The answer of a ray that met a triangle the first pass could not decide: a miss to every reader, which
// the kernel replaces by the whole test's answer.
inline constexpr std::int32_t kUndecided = -2;

// A traversal's answer at its end: `best`, unless a deferred triangle could change it. An any-hit answer
// that found a hit stands whatever was deferred; a closest hit, or a miss, may not.
template <bool kAnyHit, class RayData>
LANCER_HOST_DEVICE Hit settled(const RayData& /*a test that decides every triangle*/, const Hit& best) {
    return best;
}
template <bool kAnyHit, class Test>
LANCER_HOST_DEVICE Hit settled(const FirstPassRayData<Test>& ray, const Hit& best) {
    if (!ray.undecided || (kAnyHit && best.prim >= 0)) return best;
    Hit undecided;
    undecided.prim = kUndecided;
    return undecided;
}

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
