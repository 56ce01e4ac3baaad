// Transparent huge pages for the builds' large arrays. A first touch of a 4 KiB page costs a page fault,
// and on the VMs lancer is measured on one fault costs about 13 us: touching 200 MB took 670 ms, as long as
// building the dragon's binary BVH, and 20 ms in 2 MiB pages (docs/accel/parallel-build.md, "Page
// faults"). Embree's allocator asks for huge pages the same way (madvise on Linux).
#pragma once

#include <cstddef>
#include <vector>

namespace lancer {

// Asks the kernel to back the whole 2 MiB pages inside [data, data + bytes) with huge pages when they are
// first touched; does nothing for small ranges or where the system has no such request (not Linux, or
// transparent huge pages off). Memory already touched keeps its pages.
void advise_huge_pages(const void* data, std::size_t bytes);

// v.reserve(count), the new storage advised into huge pages before anything touches it: for arrays that a
// build fills once (references, nodes, blocks).
template <class T, class Allocator>
void reserve_huge_pages(std::vector<T, Allocator>& v, std::size_t count) {
    v.reserve(count);
    advise_huge_pages(v.data(), v.capacity() * sizeof(T));
}

}  // namespace lancer
