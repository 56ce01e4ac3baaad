// The node slots the BVH builders write their nodes into, which let subtrees build in parallel into a layout
// that does not depend on the thread count (docs/accel/parallel-build.md).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/build.hpp"
#include "core/huge_pages.hpp"

namespace lancer {

// Node slots: a subtree that may hold up to n references has at most 2n - 1 nodes, so a node in slot i
// whose first child may hold n_first references puts that child in slot i + 1 and its second in slot
// i + 2 n_first. Without spatial splits n is the subtree's reference count; with them, its capacity
// (RefRange, binned_builder.hpp). Subtrees built in parallel write disjoint slots, and compact() renumbers
// the used slots depth first: the layout does not depend on which task finished first.
class NodeSlots {
  public:
    explicit NodeSlots(std::size_t capacity)
        : slots_(std::allocator<BvhNode>().allocate(2 * capacity - 1), StorageDeleter{2 * capacity - 1}),
          used_(2 * capacity - 1, 0) {
        advise_huge_pages(slots_.get(), (2 * capacity - 1) * sizeof(BvhNode));
    }

    void set_leaf(std::size_t slot, const Box3f& bounds, std::size_t first, std::size_t count) {
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.offset = static_cast<std::uint32_t>(first);
        node.prim_count = static_cast<std::uint16_t>(count);
        used_[slot] = 1;
    }
    // Returns the slots of the two children.
    std::pair<std::size_t, std::size_t> set_inner(std::size_t slot, const Box3f& bounds, int axis,
                                                  std::size_t first_child_capacity) {
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.axis = static_cast<std::uint8_t>(axis);
        node.offset = static_cast<std::uint32_t>(slot + 2 * first_child_capacity);
        used_[slot] = 1;
        return {slot + 1, node.offset};
    }

    // The nodes depth first, each box grown by the scene's geometric tolerance (docs/numerical-contract.md,
    // "Boxes"), and the leaves' primitives in the same order: `prim_at(i)` is the primitive of the reference
    // at position i, which the leaves' offsets index until they are renumbered here (a spatial split build
    // leaves unused positions between its leaves); there are at most `references` of them.
    template <class PrimAt>
    [[nodiscard]] BvhBuildResult compact(PrimAt&& prim_at, std::size_t references) const {
        BvhBuildResult result;
        std::vector<BvhNode>& nodes = result.nodes;
        reserve_huge_pages(nodes, static_cast<std::size_t>(std::count(used_.begin(), used_.end(), 1)));
        reserve_huge_pages(result.prim_indices, references);
        const Vec3f margin(geometric_tolerance(slots_[0].bounds()));
        // Depth first from the root: (slot, index of the parent whose second-child offset awaits it).
        std::vector<std::pair<std::size_t, std::size_t>> pending = {{0, SIZE_MAX}};
        while (!pending.empty()) {
            const auto [slot, parent] = pending.back();
            pending.pop_back();
            if (parent != SIZE_MAX) nodes[parent].offset = static_cast<std::uint32_t>(nodes.size());
            BvhNode node = slots_[slot];
            node.lo -= margin, node.hi += margin;
            if (node.is_leaf()) {
                const std::uint32_t first = node.offset;
                node.offset = static_cast<std::uint32_t>(result.prim_indices.size());
                for (std::uint32_t i = first; i < first + node.prim_count; ++i)
                    result.prim_indices.push_back(prim_at(i));
            }
            nodes.push_back(node);
            if (!node.is_leaf()) {
                pending.push_back(
                    {node.offset, nodes.size() - 1});     // second child, after the first's subtree
                pending.push_back({slot + 1, SIZE_MAX});  // first child: the very next node
            }
        }
        return result;
    }

  private:
    // The slots are allocated, not initialised (2n - 1 of them, about twice the nodes a tree uses): a node is
    // constructed in its slot when set, and compact() reads only the nodes reached from the root.
    struct StorageDeleter {
        std::size_t count;
        void operator()(BvhNode* nodes) const { std::allocator<BvhNode>().deallocate(nodes, count); }
    };
    std::unique_ptr<BvhNode[], StorageDeleter> slots_;
    std::vector<std::uint8_t> used_;
};

}  // namespace lancer
