#include "lancer/huge_pages.hpp"

#include <cstddef>
#include <cstdint>
#include <new>

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

void* allocate_huge_pages(std::size_t bytes) {
    const std::size_t rounded = round_up_to_huge_page(bytes);
    void* memory = ::operator new (rounded, std::align_val_t{kHugePageBytes});
    advise_huge_pages(memory, rounded);
    return memory;
}

void deallocate_huge_pages(void* memory, std::size_t bytes) noexcept {
    ::operator delete (memory, round_up_to_huge_page(bytes), std::align_val_t{kHugePageBytes});
}

}  // namespace lancer
