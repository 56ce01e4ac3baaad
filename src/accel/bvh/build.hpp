// The build of the binary BVH: build.cpp hands the primitives to the SAH builder the options name
// (sweep_builder.cpp, binned_builder.cpp); both return the same depth-first layout.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "accel/bvh/bvh.hpp"

namespace lancer {

struct BvhBuildResult {
    HugePageVector<BvhNode> nodes;
    HugePageVector<std::uint32_t> prim_indices;
};

// The unit costs of the SAH (MacDonald & Booth 1990) the builders minimise and the costs below report.
inline constexpr float kSahNodeCost = 1.0f;
inline constexpr float kSahPrimitiveCost = 1.0f;

// Deterministic: the same geometry and options give the same nodes, whatever the thread count.
//
// Nodes of at most `whole_leaf_size` references (at most BvhAccel::kMaxLeafSize) become leaves without
// being split, their references in the order they reached the node. A wide BVH keeps every binary subtree
// of at most one triangle block's references as one leaf (bvh_wide.cpp), so the levels below those
// subtrees are work it would drop. 0: every node splits while the SAH says so.
[[nodiscard]] BvhBuildResult build_bvh(const Geometry& geometry, const BvhOptions& options,
                                       std::size_t whole_leaf_size = 0);

// The same tree over boxes, for a BVH whose leaves are not primitives of a Geometry (the instances of a
// two-level scene): references `ids`, each with the box boxes[id]. Spatial splits are off, a box having
// nothing to cut.
[[nodiscard]] BvhBuildResult build_bvh_over_boxes(std::span<const Box3f> boxes,
                                                  std::span<const std::uint32_t> ids,
                                                  const BvhOptions& options);

// SAH cost of a built hierarchy, normalised by the root's area, with unit node and primitive costs:
// sum over inner nodes of A(node) / A(root) + sum over leaves of A(leaf) / A(root) * primitives; a tree
// whose root has no area costs its primitive references.
[[nodiscard]] double bvh_sah_cost(const HugePageVector<BvhNode>& nodes);

}  // namespace lancer
