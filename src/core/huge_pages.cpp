#include "core/huge_pages.hpp"

#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace lancer {

void advise_huge_pages([[maybe_unused]] const void* data, [[maybe_unused]] std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    // Below two huge pages a range may hold none whole: not worth the system call.
    if (data == nullptr || bytes < 2 * kHugePageBytes) return;
    // madvise wants a page-aligned start; the kernel then uses huge pages for the 2 MiB-aligned parts.
    const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
    const auto begin = reinterpret_cast<std::uintptr_t>(data);
    const std::uintptr_t first = (begin + page - 1) / page * page;
    const std::uintptr_t end = begin + bytes;
    // A failure (EINVAL where transparent huge pages are compiled out) leaves the 4 KiB pages: only speed.
    madvise(reinterpret_cast<void*>(first), end - first, MADV_HUGEPAGE);
#endif
}

}  // namespace lancer
