// The binned builder's small subtrees: a full sweep (full_sweep.hpp) over centroid orders ranked once, at
// the subtree's root.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "accel/bvh/bin_box.hpp"
#include "accel/bvh/binned_builder.hpp"
#include "accel/bvh/node_slots.hpp"

namespace lancer {

// Subtrees of at most this many references are built by SmallSubtree: the exact sweep over their sorted
// centroids is both better and cheaper than clearing and scanning the bins.
inline constexpr std::size_t kExactSplitBelow = 32;

// A subtree of at most kExactSplitBelow references: every boundary between consecutive centroids on each
// axis is a candidate. The three centroid orders (centroid_less) are ranked once, at the subtree's root, and
// each split hands its children their orders by a stable partition, as in Iehl, "Intersections" (2011): the
// tree is the one that ranking at every node gives, for a fraction of the build time (docs/accel/bvh.md,
// "Small subtrees sorted once").
class SmallSubtree {
  public:
    // The subtree over refs[range.begin, range.end), whose leaves hold at most `max_leaf` references, and
    // whose nodes of at most `whole_leaf_size` references are leaves (build_bvh).
    SmallSubtree(BuildRefs& refs, int max_leaf, std::size_t whole_leaf_size, NodeSlots& slots,
                 const RefRange& range);

    // The node whose references are at positions [first, first + range.size()) of every order, and whose
    // references' array order is that of `arrival_axis`'s order there (its parent's split axis; -1: the
    // order they came in, for the subtree's root).
    void build(std::size_t slot, const RefRange& range, int depth, const Box3f& bounds, std::size_t first = 0,
               int arrival_axis = -1);

  private:
    struct NodeRefs;

    // The boxes of the references at [first, first + count) of `axis`'s order, in that order: the bits
    // the binned builder's bounds_of gives over the same array (for a median split; the sweep gives a
    // split's bounds).
    [[nodiscard]] Box3f bounds_of(int axis, std::size_t first, std::size_t count) const;

    BuildRefs& builder_refs_;
    int max_leaf_;
    std::size_t whole_leaf_size_;
    NodeSlots& slots_;
    std::array<BuildRef, kExactSplitBelow> refs_;
    std::array<BinBox, kExactSplitBelow> boxes_;
    std::array<std::array<float, kExactSplitBelow>, 3> keys_;
    // Per axis, the subtree's references (indices into refs_) in centroid order, each node's at its own
    // positions.
    std::array<std::array<std::uint8_t, kExactSplitBelow>, 3> orders_;
};

}  // namespace lancer
