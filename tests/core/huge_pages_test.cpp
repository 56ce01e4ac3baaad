// HugePageAllocator (include/lancer/huge_pages.hpp): storage of two huge pages or more starts on a 2 MiB
// boundary, so that madvise can give every page of it a huge page; smaller storage is the heap's. Both hold
// what is written.
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>

#include "lancer/huge_pages.hpp"

namespace lancer {
namespace {

TEST(HugePageAllocator, LargeStorageStartsOnAHugePageAndHoldsItsValues) {
    // 5 MiB: not a whole number of huge pages, and below glibc's largest mmap threshold (32 MiB), so that
    // glibc may take it from its heap or map it afresh; either way it starts on a huge page.
    constexpr std::size_t kCount = (std::size_t{5} << 20) / sizeof(std::uint64_t);
    static_assert(HugePageAllocator<std::uint64_t>::in_huge_pages(kCount));
    HugePageVector<std::uint64_t> values(kCount);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(values.data()) % kHugePageBytes, 0u);
    std::iota(values.begin(), values.end(), std::uint64_t{7});
    // Grown past its capacity, it moves into new aligned storage with its values.
    values.push_back(1);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(values.data()) % kHugePageBytes, 0u);
    for (std::size_t i = 0; i < kCount; i += 4099)
        ASSERT_EQ(values[i], i + 7) << i;
    EXPECT_EQ(values.back(), 1u);
}

TEST(HugePageAllocator, SmallStorageComesFromTheHeap) {
    HugePageVector<int> small(1000, 3);
    EXPECT_EQ(std::accumulate(small.begin(), small.end(), 0), 3000);
    // Rebound to another type, as containers do, it allocates that type.
    HugePageAllocator<double> doubles{HugePageAllocator<int>{}};
    double* storage = doubles.allocate(16);
    storage[15] = 2.5;
    EXPECT_EQ(storage[15], 2.5);
    doubles.deallocate(storage, 16);
}

}  // namespace
}  // namespace lancer
