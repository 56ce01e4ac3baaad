// The sweep builder: a full sweep over every centroid boundary at every node (full_sweep.hpp), serial.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <span>
#include <vector>

#include "accel/bvh/build_common.hpp"
#include "accel/bvh/full_sweep.hpp"
#include "accel/bvh/node_slots.hpp"

namespace lancer {
namespace {

// The references are sorted once per axis by centroid (ties by primitive index) and every node's are a range
// of positions of the three orders.
class SweepBuilder {
  public:
    SweepBuilder(BuildRefs& refs, const BvhOptions& options, std::size_t whole_leaf_size)
        : refs_(refs),
          max_leaf_(leaf_size_limit(options)),
          whole_leaf_size_(whole_leaf_size),
          on_left_(refs.size()),
          right_boxes_(refs.size()),
          scratch_(refs.size()) {
        for (int axis = 0; axis < 3; ++axis) {
            std::vector<std::uint32_t>& order = orders_[static_cast<std::size_t>(axis)];
            order.resize(refs.size());
            std::iota(order.begin(), order.end(), 0u);
            std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
                return centroid_less(refs[a], refs[b], axis);
            });
        }
    }

    [[nodiscard]] Box3f bounds_of(std::size_t begin, std::size_t end) const {
        Box3f bounds;
        for (std::size_t i = begin; i < end; ++i)
            bounds.extend(refs_[orders_[0][i]].bounds);
        return bounds;
    }

    // The node over positions [begin, end) of the orders, whose references `bounds` bounds.
    void build(NodeSlots& slots, std::size_t slot, std::size_t begin, std::size_t end, int depth,
               const Box3f& bounds) {
        const NodeRefs node{*this, begin};
        const std::size_t count = end - begin;
        const bool whole = count <= whole_leaf_size_;
        SweepSplit<Box3f> sweep;
        if (!whole && depth < kMedianSplitDepth)
            sweep = best_sweep_split(node, count, std::span(right_boxes_).subspan(begin, count));
        Split& split = sweep.split;
        if (whole || stays_leaf(count, bounds.surface_area(), split, max_leaf_)) {
            slots.set_leaf(slot, bounds, begin, count);
            return;
        }
        // A median split's sides were not swept.
        const bool median = split.axis < 0;
        if (median) split = median_sweep_split(node, count);
        partition_sweep_orders(node, count, split, on_left_.data(), scratch_.data());
        const std::size_t middle = begin + split.left_count;
        if (median) {
            sweep.left_bounds = bounds_of(begin, middle), sweep.right_bounds = bounds_of(middle, end);
        }
        const auto [first, second] = slots.set_inner(slot, bounds, split.axis);
        build(slots, first, begin, middle, depth + 1, sweep.left_bounds);
        build(slots, second, middle, end, depth + 1, sweep.right_bounds);
    }

    // The primitive at position i of the leaves' ranges.
    [[nodiscard]] std::uint32_t prim_at(std::size_t i) const { return refs_[orders_[0][i]].prim; }

  private:
    // A node's references, from position `begin` of each order, as full_sweep.hpp reads them.
    struct NodeRefs {
        using Index = std::uint32_t;
        using Box = Box3f;

        SweepBuilder& builder;
        std::size_t begin;

        [[nodiscard]] static Box3f empty_box() { return {}; }
        [[nodiscard]] static float area(const Box3f& box) { return box.surface_area(); }
        [[nodiscard]] Index* order(int axis) const {
            return builder.orders_[static_cast<std::size_t>(axis)].data() + begin;
        }
        [[nodiscard]] const Box3f& box(Index ref) const { return builder.refs_[ref].bounds; }
        [[nodiscard]] float centroid(Index ref, int axis) const { return builder.refs_[ref].centroid[axis]; }
        [[nodiscard]] const Vec3f& centroid_point(Index ref) const { return builder.refs_[ref].centroid; }
    };

    BuildRefs& refs_;
    int max_leaf_;
    std::size_t whole_leaf_size_;
    std::array<std::vector<std::uint32_t>, 3> orders_;
    std::vector<std::uint8_t> on_left_;
    std::vector<Box3f> right_boxes_;
    std::vector<std::uint32_t> scratch_;
};

}  // namespace

BvhBuildResult build_sweep_sah(BuildRefs& refs, const BvhOptions& options, std::size_t whole_leaf_size) {
    NodeSlots slots(refs.size());
    SweepBuilder builder(refs, options, whole_leaf_size);
    builder.build(slots, 0, 0, refs.size(), 0, builder.bounds_of(0, refs.size()));
    return slots.compact([&](std::size_t i) { return builder.prim_at(i); });
}

}  // namespace lancer
