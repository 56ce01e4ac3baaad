// HugePageAllocator (src/core/huge_pages.hpp): storage of 32 MiB or more starts on a 2 MiB boundary, so that
// madvise can give every page of it a huge page; smaller storage is the heap's. Both hold what is written.
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>

#include "core/huge_pages.hpp"

namespace lancer {
namespace {

TEST(HugePageAllocator, LargeStorageStartsOnAHugePageAndHoldsItsValues) {
    constexpr std::size_t kCount = (std::size_t{33} << 20) / sizeof(std::uint64_t);  // 33 MiB
    static_assert(HugePageAllocator<std::uint64_t>::kMappedBytes <= kCount * sizeof(std::uint64_t));
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
