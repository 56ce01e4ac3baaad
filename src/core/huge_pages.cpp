#include "lancer/huge_pages.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <new>

#include "core/parallel.hpp"

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace lancer {
namespace {

[[nodiscard]] std::uintptr_t round_up_to_huge_page(std::uintptr_t bytes) {
    return (bytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
}

}  // namespace

void advise_huge_pages([[maybe_unused]] const void* data, [[maybe_unused]] std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    const auto begin = reinterpret_cast<std::uintptr_t>(data);
    const std::uintptr_t end = begin + bytes;
    // A range that holds no whole huge page gains nothing: not worth the system call.
    if (data == nullptr || round_up_to_huge_page(begin) + kHugePageBytes > end) return;
    // madvise wants a page-aligned start; the kernel then uses huge pages for the 2 MiB-aligned parts.
    const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
    const std::uintptr_t first = (begin + page - 1) / page * page;
    // A failure (EINVAL where transparent huge pages are compiled out) leaves the 4 KiB pages: only speed.
    madvise(reinterpret_cast<void*>(first), end - first, MADV_HUGEPAGE);
#endif
}

void touch_pages(void* data, std::size_t bytes) {
    constexpr std::uintptr_t kPageBytes = 4096;
    // 64 pages a task: a quarter of a MiB, enough to pay for a task, small enough for both threads to share
    // an array of a MiB.
    constexpr std::size_t kPagesPerTask = 64;
    if (bytes == 0) return;
    const auto begin = reinterpret_cast<std::uintptr_t>(data);
    const std::uintptr_t first_page = begin / kPageBytes * kPageBytes;
    const std::size_t pages = (begin + bytes - first_page + kPageBytes - 1) / kPageBytes;
    parallel::for_each_chunk(0, pages, kPagesPerTask, [&](std::size_t from, std::size_t to) {
        for (std::size_t page = from; page < to; ++page) {
            // The first page's start may lie before `data`: its first byte of the range stands in for it.
            const std::uintptr_t address = std::max(begin, first_page + page * kPageBytes);
            *reinterpret_cast<volatile unsigned char*>(address) = 0;
        }
    });
}

void* allocate_huge_pages(std::size_t bytes) {
    const std::size_t rounded = round_up_to_huge_page(bytes);
    void* memory = ::operator new (rounded, std::align_val_t{kHugePageBytes});
    advise_huge_pages(memory, rounded);
    touch_pages(memory, bytes);
    return memory;
}

void deallocate_huge_pages(void* memory, [[maybe_unused]] std::size_t bytes) noexcept {
    // The unsized form: clang before 19 declares the sized one only under -fsized-deallocation.
    ::operator delete (memory, std::align_val_t{kHugePageBytes});
}

}  // namespace lancer
