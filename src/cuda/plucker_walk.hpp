// The Plücker octree walk on the GPU: accel/plucker/walk.hpp's walk, the CPU structures' own source, over
// the arrays in device memory and the tables in constant memory, with each leaf's triangles tested one at a
// time (intersect_leaf) where the CPU tests them in SIMD blocks. Triangles only: the caller refuses layouts
// with spheres (CudaTracer, flatten.cpp's plucker_view).
#pragma once

#include "accel/plucker/walk.hpp"
#include "cuda/bvh_traversal.hpp"
#include "cuda/gpu_layout.hpp"
#include "cuda/triangle.hpp"

namespace lancer::gpu {

// The Plücker layout a walk is compiled for (PluckerView::balanced and stored_boxes), as one type that the
// launch code passes down with the kernel's other choices.
template <bool kBalancedLayout, bool kStoredBoxesLayout>
struct WalkLayout {
    static constexpr bool kBalanced = kBalancedLayout;
    static constexpr bool kStoredBoxes = kStoredBoxesLayout;
};
using SeedLayout = WalkLayout<true, true>;  // the default: 2:1 balanced, stored boxes

// The closest hit of one ray (ties to the smaller primitive index), a miss for an invalid ray. kAnyHit
// (occlusion) ends the walk at the first leaf with a hit in [tnear, tfar].
template <class TriangleTestT, class Layout, bool kAnyHit = false, class Steps = NoSteps>
LANCER_HOST_DEVICE Hit trace_plucker(const plucker::PluckerView& octree, const plucker::PluckerTables& tables,
                                     const Ray& ray, Steps&& steps = {}) {
    Hit best;
    if (!is_valid(ray)) return best;
    const typename TriangleTestT::RayData triangle_ray(ray);
    plucker::walk<Layout::kBalanced, Layout::kStoredBoxes>(
        octree, tables, ray,
        [&](const std::uint32_t* leaf, float) {
            const bool hit = intersect_leaf<TriangleTestT, kAnyHit>(
                octree.primitives + read_only(leaf + plucker::kTriangleOffset),
                read_only(leaf + plucker::kTriangleCount), triangle_ray, ray, best);
            // Below tnear ends the walk (walk()'s contract).
            if (kAnyHit && hit) return -kInfinity;
            return hit ? best.t : ray.tfar;
        },
        steps);
    return best;
}

}  // namespace lancer::gpu
