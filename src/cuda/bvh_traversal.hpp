// The per-ray BVH traversals of Aila & Laine, "Understanding the efficiency of ray traversal on GPUs" (HPG
// 2009, section 3 and their Appendix's kernels), while-while and speculative while-while, over the 64-byte
// nodes of gpu_layout.hpp, for the device and, in tests/cuda, the host. The child boxes are tested with the
// CPU's slab test, not the paper's fma form, so that the pruning is the one proven against brute force
// (docs/cuda.md, "Kernels").
#pragma once

#include "cuda/gpu_layout.hpp"
#include "cuda/triangle.hpp"

namespace lancer::gpu {

// A leaf word can be 0x7FFFFFFF only for a BVH of 2^31 nodes: flatten_bvh refuses those.
inline constexpr std::int32_t kStackEmpty = 0x7FFFFFFF;
// Depth of the CPU BVH's inner nodes (BvhAccel::kMaxDepth) plus one: the far children pushed at once.
inline constexpr int kBvhStackSize = 97;

// The far children waiting, in local memory on the device (Aila & Laine's per-thread stack), without their
// entry distance, as in the paper: a popped node is culled by its children's boxes only.
struct TraversalStack {
    std::int32_t entries[kBvhStackSize];
    int size = 0;

    LANCER_HOST_DEVICE void push(std::int32_t node) { entries[size++] = node; }
    LANCER_HOST_DEVICE std::int32_t pop() { return size == 0 ? kStackEmpty : entries[--size]; }
};

// The vote of the speculative traversal on the host: one ray, alone in its warp.
struct LoneLane {
    LANCER_HOST_DEVICE bool any_searching(bool searching) const { return searching; }
};
// The host's model of a warp whose other lanes never stop searching: every ray postpones its first leaf
// and traverses on to a second one (the paper's other exit from the inner loop).
struct OtherLanesSearching {
    LANCER_HOST_DEVICE bool any_searching(bool) const { return true; }
};

// The per-ray cost the heatmap draws (the CPU's TraversalCounters::nodes_visited): inner nodes fetched and
// leaves tested, or octree leaves entered. A policy, so that the frame kernels pay nothing for it.
struct NoSteps {
    LANCER_HOST_DEVICE void step() {}
};
struct CountSteps {
    std::uint32_t steps = 0;
    LANCER_HOST_DEVICE void step() { ++steps; }
};

// kSpeculative false: while-while (the vote is not used). Returns the closest hit (ties to the smaller
// primitive index, as every CPU structure), a miss for an invalid ray. kAnyHit (occlusion) returns at the
// first hit in [tnear, tfar], as Aila & Laine's shadow rays do: not necessarily the closest.
template <bool kSpeculative, class TriangleTestT, bool kAnyHit = false, class Vote, class Steps = NoSteps>
LANCER_HOST_DEVICE Hit trace_bvh(const BvhView& bvh, const Ray& ray, const Vote& vote, Steps&& steps = {}) {
    Hit best;
    if (!is_valid(ray) || bvh.node_count == 0) return best;
    const typename TriangleTestT::RayData triangle_ray(ray);
    const SlabRay slab(ray);
    TraversalStack stack;

    std::int32_t node = 0;
    std::int32_t postponed = 0;  // >= 0: no leaf postponed (the speculative traversal)
    while (node != kStackEmpty) {
        // Inner nodes until a leaf (while-while) or until the warp has leaves (speculative).
        bool searching = true;
        while (node >= 0 && node != kStackEmpty) {
            const AilaLaineNode n = read_only_record(bvh.nodes + node);
            steps.step();
            const float limit = best.prim >= 0 ? best.t : ray.tfar;
            float entry0, entry1, exit;
            const bool hit0 =
                intersect_box(slab, {{n.c0_lo_x, n.c0_lo_y, n.c0_lo_z}, {n.c0_hi_x, n.c0_hi_y, n.c0_hi_z}},
                              ray.tnear, limit, entry0, exit);
            const bool hit1 =
                intersect_box(slab, {{n.c1_lo_x, n.c1_lo_y, n.c1_lo_z}, {n.c1_hi_x, n.c1_hi_y, n.c1_hi_z}},
                              ray.tnear, limit, entry1, exit);
            if (!hit0 && !hit1) {
                node = stack.pop();
            } else {
                node = hit0 ? n.child[0] : n.child[1];
                if (hit0 && hit1) {
                    // Near child first; the far one waits on the stack.
                    std::int32_t far = n.child[1];
                    if (entry1 < entry0) far = node, node = n.child[1];
                    stack.push(far);
                }
            }
            if constexpr (kSpeculative) {
                if (node < 0 && postponed >= 0) {
                    searching = false;
                    postponed = node;
                    node = stack.pop();
                }
                if (!vote.any_searching(searching)) break;
            }
        }
        if constexpr (!kSpeculative) postponed = node;
        // The postponed leaf, then the one the inner loop stopped at, if any.
        while (postponed < 0) {
            steps.step();
            if (intersect_leaf<TriangleTestT, kAnyHit>(bvh.triangles + leaf_first(postponed),
                                                       leaf_count(postponed), triangle_ray, ray, best) &&
                kAnyHit)
                return best;
            if constexpr (kSpeculative) {
                postponed = node;
                if (node < 0) node = stack.pop();
            } else {
                postponed = 0;
                node = stack.pop();
            }
        }
    }
    return best;
}

}  // namespace lancer::gpu
