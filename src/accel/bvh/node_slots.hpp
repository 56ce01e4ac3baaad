// The node slots the BVH builders write their nodes into, which let subtrees build in parallel into a layout
// that does not depend on the thread count (docs/accel/parallel-build.md).
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/build.hpp"
#include "core/huge_pages.hpp"
#include "core/parallel.hpp"

namespace lancer {

// Node slots: a subtree that may hold up to n references has at most 2n - 1 nodes, so a node in slot i
// whose first child may hold n_first references puts that child in slot i + 1 and its second in slot
// i + 2 n_first. Without spatial splits n is the subtree's reference count; with them, its capacity
// (RefRange, binned_builder.hpp). Subtrees built in parallel write disjoint slots, and compact() renumbers
// the used slots depth first: the layout does not depend on which task finished first.
class NodeSlots {
  public:
    explicit NodeSlots(std::size_t capacity)
        : slots_(uninitialised_huge_pages<BvhNode>(2 * capacity - 1)), used_(2 * capacity - 1, 0) {}

    void set_leaf(std::size_t slot, const Box3f& bounds, std::size_t first, std::size_t count) {
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.offset = static_cast<std::uint32_t>(first);
        node.prim_count = static_cast<std::uint16_t>(count);
        used_[slot] = static_cast<std::uint8_t>(kLeafUse + count);
    }
    // Returns the slots of the two children.
    std::pair<std::size_t, std::size_t> set_inner(std::size_t slot, const Box3f& bounds, int axis,
                                                  std::size_t first_child_capacity) {
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.axis = static_cast<std::uint8_t>(axis);
        node.offset = static_cast<std::uint32_t>(slot + 2 * first_child_capacity);
        used_[slot] = kInnerUse;
        return {slot + 1, node.offset};
    }

    // The nodes depth first, each box grown by the scene's geometric tolerance (docs/numerical-contract.md,
    // "Boxes"), and the leaves' primitives in the same order: `prim_at(i)` is the primitive of the reference
    // at position i, which the leaves' offsets index until they are renumbered here (a spatial split build
    // leaves unused positions between its leaves).
    //
    // Depth first order is slot order: a node's first child and its subtree fill the slots below its
    // second child's. So the used slots in increasing order are the nodes depth first, and a used slot's
    // node index is the number of used slots before it: its rank among them, read from one bit per slot
    // and the count before each 64 (0.3 MB for the dragon's 1.7 million slots, against 7 MB for an index per
    // slot). Blocks of slots are compacted in parallel, each from the counts of nodes
    // and references in the blocks before it: the same arrays whatever the threads.
    template <class PrimAt>
    [[nodiscard]] BvhBuildResult compact(PrimAt&& prim_at) const {
        const std::size_t slot_count = used_.size();
        const std::size_t blocks = (slot_count + kCompactBlock - 1) / kCompactBlock;
        const std::size_t words = (slot_count + 63) / 64;
        // Bit i of used_bits[w]: whether slot 64 w + i is used; nodes_before_word[w]: the used slots before
        // slot 64 w.
        std::vector<std::uint64_t> used_bits(words);
        std::vector<std::uint32_t> nodes_before_word(words);
        // Per block, the nodes and references of the blocks before it (prefix sums of each block's).
        std::vector<std::size_t> nodes_before(blocks + 1, 0), refs_before(blocks + 1, 0);
        parallel::for_each_block(slot_count, kCompactBlock, [&](std::size_t from, std::size_t to) {
            // From used_ alone: the used slots lie scattered over the slots' array (56 MB for the dragon),
            // which the second pass reads.
            std::size_t nodes = 0, refs = 0;
            for (std::size_t word = from / 64; word * 64 < to; ++word) {
                std::uint64_t bits = 0;
                const std::size_t last = std::min(to, word * 64 + 64);
                for (std::size_t slot = word * 64; slot < last; ++slot) {
                    const std::uint8_t use = used_[slot];
                    bits |= std::uint64_t{use != 0} << (slot - word * 64);
                    refs += use >= kLeafUse ? use - kLeafUse : 0u;
                }
                used_bits[word] = bits;
                nodes_before_word[word] = static_cast<std::uint32_t>(nodes);  // within the block, for now
                nodes += static_cast<std::size_t>(std::popcount(bits));
            }
            nodes_before[from / kCompactBlock + 1] = nodes, refs_before[from / kCompactBlock + 1] = refs;
        });
        std::partial_sum(nodes_before.begin(), nodes_before.end(), nodes_before.begin());
        std::partial_sum(refs_before.begin(), refs_before.end(), refs_before.begin());
        parallel::for_each_block(slot_count, kCompactBlock, [&](std::size_t from, std::size_t to) {
            for (std::size_t word = from / 64; word * 64 < to; ++word)
                nodes_before_word[word] += static_cast<std::uint32_t>(nodes_before[from / kCompactBlock]);
        });
        const auto node_index = [&](std::size_t slot) {
            const std::uint64_t below = (std::uint64_t{1} << (slot % 64)) - 1;
            return nodes_before_word[slot / 64] +
                   static_cast<std::uint32_t>(std::popcount(used_bits[slot / 64] & below));
        };

        BvhBuildResult result;
        reserve_huge_pages(result.nodes, nodes_before.back());
        result.nodes.resize(nodes_before.back());
        reserve_huge_pages(result.prim_indices, refs_before.back());
        result.prim_indices.resize(refs_before.back());
        const Vec3f margin(geometric_tolerance(slots_[0].bounds()));
        parallel::for_each_block(slot_count, kCompactBlock, [&](std::size_t from, std::size_t to) {
            std::size_t next_node = nodes_before[from / kCompactBlock];
            std::size_t ref_index = refs_before[from / kCompactBlock];
            for (std::size_t slot = from; slot < to; ++slot) {
                if (used_[slot] == 0) continue;
                BvhNode node = slots_[slot];
                node.lo -= margin, node.hi += margin;
                if (node.is_leaf()) {
                    for (std::uint32_t i = 0; i < node.prim_count; ++i)
                        result.prim_indices[ref_index + i] = prim_at(node.offset + i);
                    node.offset = static_cast<std::uint32_t>(ref_index);
                    ref_index += node.prim_count;
                } else {
                    node.offset = node_index(node.offset);  // the second child's slot, renumbered
                }
                result.nodes[next_node++] = node;
            }
        });
        return result;
    }

  private:
    // Slots per task of compact().
    static constexpr std::size_t kCompactBlock = std::size_t{1} << 16;
    // A block's words of used_bits are its own: its tasks write them.
    static_assert(kCompactBlock % 64 == 0);
    // used_ per slot: 0 unused, kInnerUse an inner node, kLeafUse + its reference count a leaf.
    static constexpr std::uint8_t kInnerUse = 1, kLeafUse = 2;
    static_assert(kLeafUse + BvhAccel::kMaxLeafSize <= 255);

    // The slots are allocated, not initialised (2n - 1 of them, about twice the nodes a tree uses): a node is
    // constructed in its slot when set, and compact() reads only the nodes reached from the root. In whole
    // huge pages, as compact()'s node indices: both are made and dropped on every build.
    HugePageBuffer<BvhNode> slots_;
    std::vector<std::uint8_t> used_;
};

}  // namespace lancer
