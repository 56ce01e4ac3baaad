// The checks of core/parallel.hpp, run against each backend: parallel_test.cpp includes them as the library
// is built without TBB (serial), parallel_tbb_test.cpp with it. Internal linkage, so that the two files'
// copies, which call different backends, stay apart.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <random>
#include <utility>
#include <vector>

#include "core/parallel.hpp"

namespace lancer::testing {
namespace {

constexpr std::size_t kCount = 100'003;  // prime: no chunk size divides it

inline void check_every_index_once() {
    std::vector<std::atomic<int>> visits(kCount);
    parallel::for_each_index(7, kCount, [&](std::size_t i) { visits[i].fetch_add(1); });
    for (std::size_t i = 0; i < kCount; ++i)
        ASSERT_EQ(visits[i].load(), i < 7 ? 0 : 1) << i;
    parallel::for_each_index(5, 5, [&](std::size_t) { FAIL() << "an empty range ran its body"; });
}

// `chunked`: the backend cuts the range into tasks of at most the grain (TBB), or runs it whole (serial).
inline void check_chunks_tile_the_range(bool chunked) {
    std::vector<std::atomic<int>> visits(kCount);
    std::atomic<std::size_t> chunks = 0;
    parallel::for_each_chunk(3, kCount, 1000, [&](std::size_t from, std::size_t to) {
        EXPECT_LT(from, to);
        if (chunked) {
            EXPECT_LE(to - from, 1000u);
        }
        chunks.fetch_add(1);
        for (std::size_t i = from; i < to; ++i)
            visits[i].fetch_add(1);
    });
    for (std::size_t i = 0; i < kCount; ++i)
        ASSERT_EQ(visits[i].load(), i < 3 ? 0 : 1) << i;
    EXPECT_LE(chunks.load(), kCount / 500 + 1);  // no chunk below half the grain
    if (!chunked) {
        EXPECT_EQ(chunks.load(), 1u);
    }
}

inline void check_blocks_are_fixed() {
    std::vector<std::atomic<int>> visits(kCount);
    std::atomic<std::size_t> blocks = 0;
    parallel::for_each_block(kCount, 1000, [&](std::size_t from, std::size_t to) {
        EXPECT_EQ(from % 1000, 0u);
        EXPECT_EQ(to, std::min(kCount, from + 1000));
        blocks.fetch_add(1);
        for (std::size_t i = from; i < to; ++i)
            visits[i].fetch_add(1);
    });
    for (std::size_t i = 0; i < kCount; ++i)
        ASSERT_EQ(visits[i].load(), 1) << i;
    EXPECT_EQ(blocks.load(), kCount / 1000 + 1);
}

inline void check_with_threads_runs_its_body() {
    std::atomic<int> ran = 0;
    parallel::with_threads(1,
                           [&] { parallel::for_each_index(0, 100, [&](std::size_t) { ran.fetch_add(1); }); });
    parallel::with_threads(0, [&] { ran.fetch_add(1); });
    EXPECT_EQ(ran.load(), 101);
}

inline void check_reduce_merges_every_chunk() {
    const auto sum = parallel::reduce(
        1, kCount, 64, std::uint64_t{0},
        [](std::size_t from, std::size_t to, std::uint64_t value) {
            for (std::size_t i = from; i < to; ++i)
                value += i;
            return value;
        },
        [](std::uint64_t a, std::uint64_t b) { return a + b; });
    EXPECT_EQ(sum, std::uint64_t{kCount} * (kCount - 1) / 2);
}

inline void check_invoke_runs_both() {
    std::atomic<int> ran = 0;
    parallel::invoke([&] { ran.fetch_add(1); }, [&] { ran.fetch_add(2); });
    EXPECT_EQ(ran.load(), 3);
}

inline void check_sort() {
    std::vector<std::uint32_t> values(kCount);
    std::iota(values.begin(), values.end(), 0u);
    std::shuffle(values.begin(), values.end(), std::mt19937(5));
    parallel::sort(values.begin(), values.end());
    EXPECT_TRUE(std::is_sorted(values.begin(), values.end()));
    EXPECT_EQ(values.front(), 0u);
    EXPECT_EQ(values.back(), kCount - 1);
}

inline void check_per_thread_values_are_each_threads_own() {
    parallel::PerThread<std::vector<std::size_t>> scratch;
    std::atomic<std::size_t> total = 0;
    parallel::for_each_index(0, 1000, [&](std::size_t i) {
        std::vector<std::size_t>& mine = scratch.local();
        mine.assign(8, i);  // another thread writing here would break the check below
        std::size_t sum = 0;
        for (const std::size_t value : mine)
            sum += value;
        EXPECT_EQ(sum, 8 * i);
        total.fetch_add(1);
    });
    EXPECT_EQ(total.load(), 1000u);
    EXPECT_FALSE(parallel::cancelling());
}

}  // namespace
}  // namespace lancer::testing
