// Transparent huge pages for the builds' large arrays. A first touch of a 4 KiB page costs a page fault,
// and on the VMs lancer is measured on one fault costs about 13 us: touching 200 MB took 670 ms, as long as
// building the dragon's binary BVH, and 20 ms in 2 MiB pages (docs/accel/parallel-build.md, "Page
// faults"). Embree's allocator asks for huge pages the same way (madvise on Linux).
#pragma once

#include <cstddef>
#include <memory>
#include <new>
#include <vector>

namespace lancer {

inline constexpr std::size_t kHugePageBytes = std::size_t{2} << 20;

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

// For a build's temporaries, which are made and dropped on every build. Storage of 32 MiB or more, which
// glibc maps afresh on every allocation (its largest mmap threshold), starts on a 2 MiB boundary and ends on
// one, advised into huge pages: every page of it is then a huge page. A plain allocation starts anywhere,
// and its first and last partial 2 MiB stay in 4 KiB pages, faulted again on every build (the dragon's
// references and node slots, docs/accel/parallel-build.md, "Page faults"). Smaller storage comes from the
// heap, advised as reserve_huge_pages does: a later build gets it back already faulted, which a fresh
// aligned mapping would not (the bunny's builds made 3-14 faults from the heap, 41-442 from mappings).
template <class T>
struct HugePageAllocator {
    using value_type = T;
    static constexpr std::size_t kMappedBytes = std::size_t{32} << 20;

    HugePageAllocator() = default;
    template <class U>
    HugePageAllocator(const HugePageAllocator<U>& /*other*/) {}  // NOLINT(google-explicit-constructor)

    [[nodiscard]] static bool mapped(std::size_t count) { return count * sizeof(T) >= kMappedBytes; }
    [[nodiscard]] static std::size_t rounded_bytes(std::size_t count) {
        return (count * sizeof(T) + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
    }
    [[nodiscard]] T* allocate(std::size_t count) {
        if (!mapped(count)) {
            T* memory = std::allocator<T>().allocate(count);
            advise_huge_pages(memory, count * sizeof(T));
            return memory;
        }
        void* memory = ::operator new (rounded_bytes(count), std::align_val_t{kHugePageBytes});
        advise_huge_pages(memory, rounded_bytes(count));
        return static_cast<T*>(memory);
    }
    void deallocate(T* memory, std::size_t count) {
        if (!mapped(count)) return std::allocator<T>().deallocate(memory, count);
        ::operator delete (memory, rounded_bytes(count), std::align_val_t{kHugePageBytes});
    }
    friend bool operator==(const HugePageAllocator& /*a*/, const HugePageAllocator& /*b*/) { return true; }
};

template <class T>
using HugePageVector = std::vector<T, HugePageAllocator<T>>;

// Storage for `count` T from a HugePageAllocator, allocated, not initialised: a build's scratch whose
// elements are each written before they are read, where a vector would first write them all.
template <class T>
struct HugePageDeleter {
    std::size_t count;
    void operator()(T* items) const { HugePageAllocator<T>().deallocate(items, count); }
};
template <class T>
using HugePageBuffer = std::unique_ptr<T[], HugePageDeleter<T>>;
template <class T>
[[nodiscard]] HugePageBuffer<T> uninitialised_huge_pages(std::size_t count) {
    return HugePageBuffer<T>(HugePageAllocator<T>().allocate(count), HugePageDeleter<T>{count});
}

}  // namespace lancer
