// The full sweep SAH split of Iehl, "Intersections" (2011), which both the sweep builder (sweep_builder.cpp)
// and the binned builder's small subtrees (small_subtree.cpp) make: the references are sorted once per axis
// by centroid ("trier une seule fois par axe"), every boundary between consecutive centroids is a candidate,
// and a split hands each child its references in the three orders by a stable partition, O(N) per level.
#pragma once

#include <algorithm>
#include <cstddef>
#include <span>

#include "accel/bvh/build_common.hpp"

namespace lancer {

// A node's references in the three centroid orders, each at positions [0, count) of `order(axis)`, whose
// entries are indices the `Refs` view reads:
//   typename Refs::Index              the reference indices
//   typename Refs::Box                the box type the sweep extends, with extend(box)
//   static Refs::empty_box()          the Box that bounds nothing
//   static float Refs::area(box)      the box's surface area
//   order(axis)                       the node's first entry of axis's order (Index*)
//   box(index)                        the reference's box
//   centroid(index, axis)             its centroid's coordinate on the axis
//   centroid_point(index)             its centroid
// The builders keep their own box type: the small subtrees sweep SIMD boxes (bin_box.hpp).

// A node's best split and the bounds of the references on each side of it, which its children need.
template <class Box>
struct SweepSplit {
    Split split;
    Box left_bounds, right_bounds;
};

// The node's cheapest boundary on each axis: a sweep right to left for the right boxes, then left to right
// evaluating every boundary. `right_boxes` holds at least `count` boxes of scratch.
template <class Refs>
[[nodiscard]] SweepSplit<typename Refs::Box> best_sweep_split(const Refs& refs, std::size_t count,
                                                              std::span<typename Refs::Box> right_boxes) {
    SweepSplit<typename Refs::Box> best;
    for (int axis = 0; axis < 3; ++axis) {
        const auto* order = refs.order(axis);
        auto right = Refs::empty_box();
        for (std::size_t i = count - 1; i > 0; --i) {
            right.extend(refs.box(order[i]));
            right_boxes[i] = right;
        }
        auto left = Refs::empty_box();
        for (std::size_t i = 0; i + 1 < count; ++i) {
            left.extend(refs.box(order[i]));
            // A boundary between equal centroids would not separate anything a ray could tell apart.
            if (refs.centroid(order[i], axis) == refs.centroid(order[i + 1], axis)) continue;
            const float cost = Refs::area(left) * static_cast<float>(i + 1) +
                               Refs::area(right_boxes[i + 1]) * static_cast<float>(count - i - 1);
            if (cost < best.split.cost) best = {{axis, cost, i + 1, 0}, left, right_boxes[i + 1]};
        }
    }
    return best;
}

// Applies `split`: the first split.left_count references of the split axis's order go left, and the other
// two orders keep their sequence on both sides, so that each child's references are again sorted on every
// axis. `on_left` is indexed by reference index; `right_scratch` holds at least `count` indices.
template <class Refs, class Flag>
void partition_sweep_orders(const Refs& refs, std::size_t count, const Split& split, Flag* on_left,
                            typename Refs::Index* right_scratch) {
    const auto* split_order = refs.order(split.axis);
    for (std::size_t i = 0; i < count; ++i)
        on_left[split_order[i]] = i < split.left_count;
    for (int axis = 0; axis < 3; ++axis) {
        if (axis == split.axis) continue;
        typename Refs::Index* order = refs.order(axis);
        // Branch-free: each reference is written to both sides and only its own side's end moves on (the
        // side is close to random, so a branch would mispredict often). A left write lands at or before the
        // read position, and a stale one is overwritten by a later reference or the right side's copy.
        std::size_t left_end = 0, right_end = 0;
        for (std::size_t i = 0; i < count; ++i) {
            const auto ref = order[i];
            const auto goes_left = static_cast<std::size_t>(on_left[ref]);
            order[left_end] = ref;
            right_scratch[right_end] = ref;
            left_end += goes_left;
            right_end += 1 - goes_left;
        }
        std::copy_n(right_scratch, right_end, order + left_end);
    }
}

// The object median on the axis of largest centroid extent: the split when no boundary separates the
// centroids, and past kMedianSplitDepth.
template <class Refs>
[[nodiscard]] Split median_sweep_split(const Refs& refs, std::size_t count) {
    Box3f centroids;
    const auto* order = refs.order(0);
    for (std::size_t i = 0; i < count; ++i)
        centroids.extend(refs.centroid_point(order[i]));
    return {max_axis(centroids.extent()), 0.0f, count / 2, 0};
}

}  // namespace lancer
