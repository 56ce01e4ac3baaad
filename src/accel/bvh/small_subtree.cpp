#include "accel/bvh/small_subtree.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>

#include "accel/bvh/full_sweep.hpp"

namespace lancer {

// A node's references, from position `first` of each order, as full_sweep.hpp reads them: their boxes
// swept four floats at a time, their centroids from the ranking's keys.
struct SmallSubtree::NodeRefs {
    using Index = std::uint8_t;
    using Box = BinBox;

    SmallSubtree& subtree;
    std::size_t first;

    [[nodiscard]] static BinBox empty_box() { return BinBox::none(); }
    // The sweep's boxes each hold a reference at least.
    [[nodiscard]] static float area(const BinBox& box) { return box.filled_area(); }
    [[nodiscard]] Index* order(int axis) const {
        return subtree.orders_[static_cast<std::size_t>(axis)].data() + first;
    }
    [[nodiscard]] const BinBox& box(Index ref) const { return subtree.boxes_[ref]; }
    [[nodiscard]] float centroid(Index ref, int axis) const {
        return subtree.keys_[static_cast<std::size_t>(axis)][ref];
    }
    [[nodiscard]] const Vec3f& centroid_point(Index ref) const { return subtree.refs_[ref].centroid; }
};

SmallSubtree::SmallSubtree(BuildRefs& refs, int max_leaf, std::size_t whole_leaf_size, NodeSlots& slots,
                           const RefRange& range)
    : builder_refs_(refs), max_leaf_(max_leaf), whole_leaf_size_(whole_leaf_size), slots_(slots) {
    const std::size_t count = range.size();
    // Padding sorts after every reference: its key is +inf, above every centroid.
    std::array<std::uint32_t, kExactSplitBelow> prims;
    prims.fill(std::numeric_limits<std::uint32_t>::max());
    for (auto& axis_keys : keys_)
        axis_keys.fill(kInfinity);
    for (std::size_t i = 0; i < count; ++i) {
        const BuildRef& ref = refs[range.begin + i];
        refs_[i] = ref, boxes_[i] = BinBox::of(ref), prims[i] = ref.prim;
        for (std::size_t axis = 0; axis < 3; ++axis)
            keys_[axis][i] = ref.centroid[static_cast<int>(axis)];
    }
    // Reference i goes where the count of references before it says: branch-free compares over
    // fixed-size arrays, which GCC vectorizes, where an insertion sort mispredicts half of its.
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const auto& keys = keys_[axis];
        for (std::size_t i = 0; i < count; ++i) {
            std::uint32_t rank = 0;
            for (std::size_t j = 0; j < kExactSplitBelow; ++j) {
                const auto below = static_cast<std::uint32_t>(keys[j] < keys[i]);
                const auto tie = static_cast<std::uint32_t>(keys[j] == keys[i]);
                rank += below | (tie & static_cast<std::uint32_t>(prims[j] < prims[i]));
            }
            orders_[axis][rank] = static_cast<std::uint8_t>(i);
        }
    }
}

void SmallSubtree::build(std::size_t slot, const RefRange& range, int depth, const Box3f& bounds,
                         std::size_t first, int arrival_axis) {
    const NodeRefs node{*this, first};
    const std::size_t count = range.size();
    const bool whole = count <= whole_leaf_size_;
    std::array<BinBox, kExactSplitBelow> right_boxes;
    SweepSplit<BinBox> sweep;
    if (!whole && depth < kMedianSplitDepth) sweep = best_sweep_split(node, count, std::span(right_boxes));
    Split& split = sweep.split;
    if (whole || stays_leaf(count, bounds.surface_area(), split, max_leaf_)) {
        slots_.set_leaf(slot, bounds, range.begin, count);
        for (std::size_t i = 0; i < count; ++i) {
            const std::size_t local =
                arrival_axis < 0 ? i : orders_[static_cast<std::size_t>(arrival_axis)][first + i];
            builder_refs_[range.begin + i] = refs_[local];
        }
        return;
    }
    Box3f left_bounds, right_bounds;
    if (split.axis >= 0) {
        left_bounds = sweep.left_bounds.box(), right_bounds = sweep.right_bounds.box();
    } else {
        split = median_sweep_split(node, count);
        left_bounds = bounds_of(split.axis, first, split.left_count);
        right_bounds = bounds_of(split.axis, first + split.left_count, count - split.left_count);
    }
    std::array<bool, kExactSplitBelow> on_left;
    std::array<std::uint8_t, kExactSplitBelow> right_scratch;
    partition_sweep_orders(node, count, split, on_left.data(), right_scratch.data());
    const std::size_t left_count = split.left_count, right_count = count - left_count;
    const auto [left, right] = share_free_positions(range, left_count, right_count);
    const auto [first_slot, second_slot] = slots_.set_inner(slot, bounds, split.axis);
    build(first_slot, left, depth + 1, left_bounds, first, split.axis);
    build(second_slot, right, depth + 1, right_bounds, first + left_count, split.axis);
}

Box3f SmallSubtree::bounds_of(int axis, std::size_t first, std::size_t count) const {
    Box3f bounds;
    for (std::size_t i = first; i < first + count; ++i)
        bounds.extend(refs_[orders_[static_cast<std::size_t>(axis)][i]].bounds);
    return bounds;
}

}  // namespace lancer
