// lancer/parallel.hpp, the loops the command line and the Python module share, through lancer_core as built
// (over oneTBB where it was found, serially otherwise).
#include "lancer/parallel.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <stdexcept>
#include <thread>
#include <vector>

namespace lancer::testing {
namespace {

constexpr std::size_t kIndexCount = 10'007;  // prime: the last block is shorter

TEST(ParallelFor, VisitsEveryIndexOnceInFixedBlocks) {
    std::vector<std::atomic<int>> visits(kIndexCount);
    std::atomic<bool> blocks_fixed = true;
    parallel_for(kIndexCount, 64, 0, [&](std::size_t first, std::size_t last) {
        if (first % 64 != 0 || last != std::min(kIndexCount, first + 64)) blocks_fixed = false;
        for (std::size_t i = first; i < last; ++i)
            visits[i].fetch_add(1);
    });
    EXPECT_TRUE(blocks_fixed.load());
    for (std::size_t i = 0; i < kIndexCount; ++i)
        ASSERT_EQ(visits[i].load(), 1) << i;
    parallel_for(0, 8, 0, [](std::size_t, std::size_t) { FAIL() << "an empty range ran its body"; });
}

// The most bodies that ran at once, each holding its task a moment so that any other thread joins in.
int most_at_once(int threads, int inner_threads = 0) {
    std::atomic<int> running = 0, most = 0;
    const auto loop = [&] {
        parallel_for(64, 1, inner_threads, [&](std::size_t, std::size_t) {
            const int now = running.fetch_add(1) + 1;
            int seen = most.load();
            while (now > seen && !most.compare_exchange_weak(seen, now)) {
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
            running.fetch_sub(1);
        });
    };
    if (inner_threads == 0)
        run_with_threads(threads, loop);
    else
        loop();
    return most.load();
}

TEST(ParallelFor, HonoursTheThreadCap) {
    EXPECT_EQ(most_at_once(0, 1), 1);
    EXPECT_LE(most_at_once(0, 2), 2);
    // A loop asking for the caller's threads inside run_with_threads gets that cap.
    EXPECT_EQ(most_at_once(1), 1);
    EXPECT_LE(most_at_once(2), 2);
}

// oneTBB warns on stderr, once a process, for an arena wider than the machine: a thread count above the CPUs
// is clamped, quietly (the Python module's nthreads=1000 relies on it).
TEST(ParallelFor, ClampsAThreadCountAboveTheMachineQuietly) {
    ::testing::internal::CaptureStderr();
    std::atomic<std::size_t> visited = 0;
    parallel_for(kIndexCount, 64, 100'000,
                 [&](std::size_t first, std::size_t last) { visited += last - first; });
    run_with_threads(100'000, [&] { parallel_for(kIndexCount, 64, 0, [](std::size_t, std::size_t) {}); });
    EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
    EXPECT_EQ(visited.load(), kIndexCount);
}

TEST(ParallelFor, RejectsAZeroBlock) {
    EXPECT_THROW(parallel_for(10, 0, 0, [](std::size_t, std::size_t) {}), std::invalid_argument);
}

TEST(ParallelFor, ABodysExceptionReachesTheCaller) {
    const auto throwing = [](std::size_t first, std::size_t last) {
        if (first <= 5000 && 5000 < last) throw std::out_of_range("index 5000");
    };
    EXPECT_THROW(parallel_for(kIndexCount, 16, 2, throwing), std::out_of_range);
    EXPECT_THROW(run_with_threads(2, [&] { parallel_for(kIndexCount, 16, 0, throwing); }), std::out_of_range);
    try {
        run_with_threads(1, [] { throw std::runtime_error("from the work"); });
        ADD_FAILURE() << "run_with_threads swallowed its work's exception";
    } catch (const std::runtime_error& error) {
        EXPECT_STREQ(error.what(), "from the work");
    }
}

}  // namespace
}  // namespace lancer::testing
