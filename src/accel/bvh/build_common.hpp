// What the BVH builders share: the build references, a node's split, the rule that stops splitting, and the
// builders' entry points, which build.cpp dispatches to (docs/accel/bvh.md).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "accel/bvh/build.hpp"
#include "lancer/huge_pages.hpp"

namespace lancer {

// The SAH of Iehl, "Intersections" (2011): T(child) = T_box + A(child) / A(node) N(child) T_object, with
// T_box = T_object = 1. Past this depth every split is an object median, so the depth stays below kMaxDepth
// for any input: 64 + log2(2^32) <= 96.
inline constexpr int kMedianSplitDepth = 64;
static_assert(kMedianSplitDepth + 32 <= BvhAccel::kMaxDepth);

struct BuildRef {
    Box3f bounds;
    Vec3f centroid;
    std::uint32_t prim = 0;
};

// A build's references, made and dropped on every build: in whole huge pages (HugePageAllocator).
using BuildRefs = HugePageVector<BuildRef>;

// Centroid order on one axis, ties by primitive index: a total order, so sorts are deterministic.
[[nodiscard]] inline bool centroid_less(const BuildRef& a, const BuildRef& b, int axis) {
    return a.centroid[axis] < b.centroid[axis] || (a.centroid[axis] == b.centroid[axis] && a.prim < b.prim);
}

struct Split {
    int axis = -1;  // -1: no split improves on a leaf, or none separates the references
    float cost = kInfinity;
    std::size_t left_count = 0;  // full sweep: references on the left in the axis order
    int bin = 0;                 // binned builder: first bin on the right
};

[[nodiscard]] inline int leaf_size_limit(const BvhOptions& options) {
    return std::clamp(options.max_leaf_size, 1, BvhAccel::kMaxLeafSize);
}

// Whether a node of `count` references stays a leaf given its best split (the stopping rule of Iehl,
// "Intersections" (2011): when it is no longer worth splitting), and never beyond the leaf size limit.
[[nodiscard]] inline bool stays_leaf(std::size_t count, float node_area, const Split& split, int max_leaf) {
    if (count == 1) return true;
    if (count > static_cast<std::size_t>(max_leaf)) return false;
    // A node without area (references on a line or a point): no split can be told apart by the SAH.
    if (split.axis < 0 || !(node_area > 0.0f)) return true;
    return kSahNodeCost + split.cost / node_area >= static_cast<float>(count) * kSahPrimitiveCost;
}

// The full sweep over the primitives' references (sweep_builder.cpp). Nodes of at most `whole_leaf_size`
// references are leaves (build_bvh).
[[nodiscard]] BvhBuildResult build_sweep_sah(BuildRefs& refs, const BvhOptions& options,
                                             std::size_t whole_leaf_size);

// The binned builder (binned_builder.cpp): refs[0, primitives) are the primitives' references, the rest of
// `refs` free positions for spatial splits. Nodes of at most `whole_leaf_size` references are leaves.
[[nodiscard]] BvhBuildResult build_binned_sah(BuildRefs& refs, std::size_t primitives,
                                              const Geometry& geometry, const BvhOptions& options,
                                              std::size_t whole_leaf_size);

}  // namespace lancer
