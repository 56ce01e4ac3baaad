// The node slots the BVH builders write their nodes into, which let subtrees build in parallel into a layout
// that does not depend on the thread count (docs/accel/parallel-build.md).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/build.hpp"
#include "core/huge_pages.hpp"

namespace lancer {

// Node slots: slot 0 is the root, and an inner node's two children take the next free pair of slots, handed
// out by an atomic counter as subtrees build in parallel. The slots are therefore dense (a tree of n nodes
// touches n slots), in an order that depends on the threads' timing; compact() writes the nodes depth
// first from the root, which does not. A tree over n references has at most 2n - 1 nodes.
class NodeSlots {
  public:
    explicit NodeSlots(std::size_t capacity) : slots_(uninitialised_huge_pages<BvhNode>(2 * capacity - 1)) {}

    void set_leaf(std::size_t slot, const Box3f& bounds, std::size_t first, std::size_t count) {
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.offset = static_cast<std::uint32_t>(first);
        node.prim_count = static_cast<std::uint16_t>(count);
        references_.fetch_add(count, std::memory_order_relaxed);
    }
    // Returns the slots of the two children.
    std::pair<std::size_t, std::size_t> set_inner(std::size_t slot, const Box3f& bounds, int axis) {
        const std::size_t first = next_.fetch_add(2, std::memory_order_relaxed);
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.axis = static_cast<std::uint8_t>(axis);
        node.offset = static_cast<std::uint32_t>(first);  // the first child's slot, until compact()
        return {first, first + 1};
    }

    // The nodes depth first, each box grown by the scene's geometric tolerance (docs/numerical-contract.md,
    // "Boxes"), and the leaves' primitives in the same order: `prim_at(i)` is the primitive of the reference
    // at position i, which the leaves' offsets index until they are renumbered here (a spatial split build
    // leaves unused positions between its leaves). Every slot handed out holds a node, so the tree has
    // next_ nodes; an inner node's offset becomes its second child's index once the first child's subtree
    // is written.
    template <class PrimAt>
    [[nodiscard]] BvhBuildResult compact(PrimAt&& prim_at) const {
        const std::size_t node_count = next_.load(std::memory_order_relaxed);
        BvhBuildResult result;
        reserve_huge_pages(result.nodes, node_count);
        result.nodes.resize(node_count);
        reserve_huge_pages(result.prim_indices, references_.load(std::memory_order_relaxed));
        const Vec3f margin(geometric_tolerance(slots_[0].bounds()));
        // Pending subtrees: a slot, and the written inner node whose offset its index becomes (the second
        // children), or none.
        struct Pending {
            std::size_t slot;
            std::size_t parent;
        };
        constexpr std::size_t kNone = ~std::size_t{0};
        std::vector<Pending> stack{{0, kNone}};
        std::size_t written = 0;
        while (!stack.empty()) {
            const Pending pending = stack.back();
            stack.pop_back();
            if (pending.parent != kNone)
                result.nodes[pending.parent].offset = static_cast<std::uint32_t>(written);
            BvhNode node = slots_[pending.slot];
            node.lo -= margin, node.hi += margin;
            if (node.is_leaf()) {
                const std::size_t first = result.prim_indices.size();
                for (std::uint32_t i = 0; i < node.prim_count; ++i)
                    result.prim_indices.push_back(prim_at(node.offset + i));
                node.offset = static_cast<std::uint32_t>(first);
            } else {
                stack.push_back({node.offset + std::size_t{1}, written});
                stack.push_back({node.offset, kNone});
            }
            result.nodes[written++] = node;
        }
        return result;
    }

  private:
    // The slots are allocated, not initialised (2n - 1 of them): a node is constructed in its slot when set,
    // and only the slots handed out are touched, in whole huge pages.
    HugePageBuffer<BvhNode> slots_;
    std::atomic<std::size_t> next_{1};
    std::atomic<std::size_t> references_{0};
};

}  // namespace lancer
