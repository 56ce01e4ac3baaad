// The binned builder's partition (binned_builder.cpp): the array the two-pointer partition leaves, made
// without its data-dependent branches and, over large ranges, in parallel.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/parallel.hpp"

namespace lancer {

// The two-pointer partition (one index up from the left, one down from the right, each stopping at an item
// on the wrong side, the two swapped) swaps the k-th item from the left that goes right with the k-th item
// from the right that goes left, for each k whose right-goer lies below the middle (the number of items
// that go left); every other item stays where it was. Once each item's side is known these pairs follow
// from counts, so this makes the same swaps without the scans' branches, which mispredict on sides close
// to random (a quarter of the binned build's mispredicted branches), and over blocks in parallel: the
// same array whatever the thread count.
//
// `goes_left(block_index, item)` is called once per item, in order within each block of `block` items (the
// last one shorter), and returns the item's side; blocks run concurrently, so what it accumulates it should
// keep per block. `scratch` holds `count` entries. Returns the number of items that go left.
template <class T, class GoesLeft>
std::size_t pair_partition(T* items, std::size_t count, std::size_t block, std::uint32_t* scratch,
                           GoesLeft&& goes_left) {
    // Per block, the positions of the items going right from scratch[from] up in increasing order, and
    // those going left from scratch[to - 1] down: one store per item, at an address chosen without a branch.
    auto classify = [&](std::size_t from, std::size_t to) {
        const std::size_t block_index = from / block;
        std::size_t right = from, left = to;
        for (std::size_t i = from; i < to; ++i) {
            const bool is_left = goes_left(block_index, items[i]);
            left -= static_cast<std::size_t>(is_left);
            scratch[is_left ? left : right] = static_cast<std::uint32_t>(i);
            right += static_cast<std::size_t>(!is_left);
        }
        return to - left;
    };
    if (count <= block) {
        const std::size_t middle = classify(0, count), going_right = count - middle;
        // scratch[going_right] holds the last item going left.
        for (std::size_t k = 0; k < going_right && scratch[k] < middle; ++k)
            std::swap(items[scratch[k]], items[scratch[going_right + k]]);
        return middle;
    }

    const std::size_t blocks = (count + block - 1) / block;
    std::vector<std::size_t> lefts(blocks);
    parallel::for_each_block(
        count, block, [&](std::size_t from, std::size_t to) { lefts[from / block] = classify(from, to); });
    // Per block, the items going right in the blocks before it, and those going left in it and after it.
    std::vector<std::size_t> rights_before(blocks + 1, 0), lefts_from(blocks + 1, 0);
    for (std::size_t b = 0; b < blocks; ++b) {
        const std::size_t size = std::min(count, (b + 1) * block) - b * block;
        rights_before[b + 1] = rights_before[b] + size - lefts[b];
    }
    for (std::size_t b = blocks; b-- > 0;)
        lefts_from[b] = lefts_from[b + 1] + lefts[b];
    const std::size_t middle = lefts_from[0];
    // Each block swaps its items going right that lie below the middle: the k-th going right overall with
    // the k-th going left from the right, which block g holds for k in [lefts_from[g + 1], lefts_from[g]).
    parallel::for_each_block(count, block, [&](std::size_t from, std::size_t to) {
        const std::size_t b = from / block, going_right = (to - from) - lefts[b];
        if (going_right == 0 || scratch[from] >= middle) return;
        const std::size_t first_rank = rights_before[b];
        // The block before the first whose lefts_from is at most first_rank (lefts_from does not increase).
        const auto first_below =
            std::partition_point(lefts_from.begin(), lefts_from.begin() + static_cast<std::ptrdiff_t>(blocks),
                                 [&](std::size_t from_here) { return from_here > first_rank; });
        auto holder = static_cast<std::size_t>(first_below - lefts_from.begin()) - 1;
        for (std::size_t j = 0; j < going_right && scratch[from + j] < middle; ++j) {
            const std::size_t rank = first_rank + j;
            while (rank >= lefts_from[holder])
                --holder;
            const std::size_t holder_from = holder * block;
            const std::size_t holder_right =
                std::min(count, holder_from + block) - holder_from - lefts[holder];
            const std::size_t partner = scratch[holder_from + holder_right + (rank - lefts_from[holder + 1])];
            std::swap(items[scratch[from + j]], items[partner]);
        }
    });
    return middle;
}

}  // namespace lancer
