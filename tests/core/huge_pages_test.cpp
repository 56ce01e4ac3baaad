// HugePageAllocator (include/lancer/huge_pages.hpp): storage of two huge pages or more starts on a 2 MiB
// boundary, so that madvise can give every page of it a huge page; smaller storage is the heap's. Both hold
// what is written. Large storage comes back with its pages faulted (touch_pages).
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

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

#if defined(__linux__)
constexpr std::size_t kPage = 4096;

// Which 4 KiB pages of [data, data + pages * 4 KiB) are resident (mincore), data page-aligned.
std::vector<bool> resident_pages(const void* data, std::size_t pages) {
    std::vector<unsigned char> flags(pages);
    EXPECT_EQ(mincore(const_cast<void*>(data), pages * kPage, flags.data()), 0);
    std::vector<bool> resident(pages);
    for (std::size_t page = 0; page < pages; ++page)
        resident[page] = (flags[page] & 1) != 0;
    return resident;
}

// A range that starts and ends inside a page has both end pages faulted, and nothing around it is touched.
TEST(TouchPages, FaultsEveryPageOfTheRangeAndNoOther) {
    constexpr std::size_t kPages = 64;
    void* mapped = mmap(nullptr, kPages * kPage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    ASSERT_NE(mapped, MAP_FAILED);
    auto* const base = static_cast<unsigned char*>(mapped);
    for (const bool page_resident : resident_pages(base, kPages))
        ASSERT_FALSE(page_resident);
    // From 100 bytes into page 2 to 1 byte into page 43: pages 2 to 43.
    touch_pages(base + 2 * kPage + 100, 41 * kPage - 99);
    const std::vector<bool> resident = resident_pages(base, kPages);
    for (std::size_t page = 0; page < kPages; ++page)
        EXPECT_EQ(resident[page], page >= 2 && page <= 43) << "page " << page;
    munmap(mapped, kPages * kPage);
}

// Both kinds of large storage come back faulted: the huge-page storage and the heap's from kTouchedBytes.
TEST(HugePageAllocator, LargeStorageComesBackFaulted) {
    HugePageAllocator<unsigned char> bytes;
    for (const std::size_t size :
         {HugePageAllocator<unsigned char>::kTouchedBytes + 12345, std::size_t{6} << 20}) {
        unsigned char* storage = bytes.allocate(size);
        const auto address = reinterpret_cast<std::uintptr_t>(storage);
        const std::uintptr_t first = address / kPage * kPage;
        const std::size_t pages = (address + size - first + kPage - 1) / kPage;
        const std::vector<bool> resident = resident_pages(reinterpret_cast<void*>(first), pages);
        std::size_t missing = 0;
        for (const bool page_resident : resident)
            missing += page_resident ? 0 : 1;
        EXPECT_EQ(missing, 0u) << "of " << pages << " pages, storage of " << size << " bytes";
        bytes.deallocate(storage, size);
    }
}
#endif

}  // namespace
}  // namespace lancer
