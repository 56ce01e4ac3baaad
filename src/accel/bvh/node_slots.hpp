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
#include "core/parallel.hpp"
#include "lancer/huge_pages.hpp"

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
    // next_ nodes. The subtrees below depth kSplitDepth are counted, then written, in parallel, each where
    // the counts of those before it (depth first) place it; the nodes above them are written in between.
    template <class PrimAt>
    [[nodiscard]] BvhBuildResult compact(PrimAt&& prim_at) const {
        BvhBuildResult result;
        result.nodes.resize(next_.load(std::memory_order_relaxed));
        const Vec3f margin(geometric_tolerance(slots_[0].bounds()));
        std::vector<Subtree> subtrees;
        collect_subtrees(0, 0, subtrees);
        parallel::for_each_index(0, subtrees.size(), [&](std::size_t i) { count(subtrees[i]); });
        // Every leaf lies in a subtree.
        std::size_t references = 0;
        for (const Subtree& subtree : subtrees)
            references += subtree.refs;
        result.prim_indices.resize(references);
        Placement placement;
        place_top(0, 0, margin, subtrees, placement, result);
        parallel::for_each_index(0, subtrees.size(),
                                 [&](std::size_t i) { write(subtrees[i], margin, prim_at, result); });
        return result;
    }

  private:
    // Depth below which compact() splits the tree into subtrees: up to 2^6, for the threads to share.
    static constexpr int kSplitDepth = 6;
    static constexpr std::size_t kNoParent = ~std::size_t{0};

    // A subtree compact() writes whole: its root's slot, its nodes and leaf references, and where they go.
    struct Subtree {
        std::size_t slot;
        std::size_t nodes = 0, refs = 0;
        std::size_t first_node = 0, first_ref = 0;
    };

    // Where compact() writes next: a node, a leaf reference, and the next subtree in depth-first order.
    struct Placement {
        std::size_t node = 0, ref = 0, subtree = 0;
    };

    // Whether a node at `depth` roots a subtree that compact() writes whole: the nodes at kSplitDepth, and
    // the leaves above it. collect_subtrees lists those roots depth first.
    [[nodiscard]] static bool is_subtree(const BvhNode& node, int depth) {
        return depth == kSplitDepth || node.is_leaf();
    }
    void collect_subtrees(std::size_t slot, int depth, std::vector<Subtree>& subtrees) const {
        const BvhNode& node = slots_[slot];
        if (is_subtree(node, depth)) {
            subtrees.push_back({slot});
            return;
        }
        collect_subtrees(node.offset, depth + 1, subtrees);
        collect_subtrees(node.offset + std::size_t{1}, depth + 1, subtrees);
    }
    // The nodes above the subtrees, depth first as collect_subtrees walks them, each subtree given its
    // place from the counts of those before it; an inner node's offset is its second child's index.
    void place_top(std::size_t slot, int depth, const Vec3f& margin, std::vector<Subtree>& subtrees,
                   Placement& at, BvhBuildResult& result) const {
        const BvhNode& node = slots_[slot];
        if (is_subtree(node, depth)) {
            Subtree& placed = subtrees[at.subtree++];
            placed.first_node = at.node, placed.first_ref = at.ref;
            at.node += placed.nodes, at.ref += placed.refs;
            return;
        }
        const std::size_t index = at.node++;
        BvhNode& written = result.nodes[index];
        written = node;
        written.lo -= margin, written.hi += margin;
        place_top(node.offset, depth + 1, margin, subtrees, at, result);
        written.offset = static_cast<std::uint32_t>(at.node);
        place_top(node.offset + std::size_t{1}, depth + 1, margin, subtrees, at, result);
    }

    void count(Subtree& subtree) const {
        std::vector<std::size_t> stack{subtree.slot};
        while (!stack.empty()) {
            const BvhNode& node = slots_[stack.back()];
            stack.pop_back();
            ++subtree.nodes;
            if (node.is_leaf()) {
                subtree.refs += node.prim_count;
            } else {
                stack.push_back(node.offset + std::size_t{1});
                stack.push_back(node.offset);
            }
        }
    }

    // The subtree depth first from its first_node and first_ref: an inner node's offset becomes its second
    // child's index once the first child's subtree is written.
    template <class PrimAt>
    void write(const Subtree& subtree, const Vec3f& margin, PrimAt& prim_at, BvhBuildResult& result) const {
        struct Pending {
            std::size_t slot;
            std::size_t parent;  // the written inner node whose second child this is, or kNoParent
        };
        std::vector<Pending> stack{{subtree.slot, kNoParent}};
        std::size_t next_node = subtree.first_node, next_ref = subtree.first_ref;
        while (!stack.empty()) {
            const Pending pending = stack.back();
            stack.pop_back();
            if (pending.parent != kNoParent)
                result.nodes[pending.parent].offset = static_cast<std::uint32_t>(next_node);
            BvhNode node = slots_[pending.slot];
            node.lo -= margin, node.hi += margin;
            if (node.is_leaf()) {
                for (std::uint32_t i = 0; i < node.prim_count; ++i)
                    result.prim_indices[next_ref + i] = prim_at(node.offset + i);
                node.offset = static_cast<std::uint32_t>(next_ref);
                next_ref += node.prim_count;
            } else {
                stack.push_back({node.offset + std::size_t{1}, next_node});
                stack.push_back({node.offset, kNoParent});
            }
            result.nodes[next_node++] = node;
        }
    }

    // The slots are allocated, not initialised (2n - 1 of them): a node is constructed in its slot when set,
    // and only the slots handed out are touched, in whole huge pages.
    HugePageBuffer<BvhNode> slots_;
    std::atomic<std::size_t> next_{1};
};

}  // namespace lancer
