// Transparent huge pages for large arrays: the builds' temporaries, the structures' nodes and leaves, the
// scene's flattened triangles. A first touch of a 4 KiB page costs a page fault, and on the VMs lancer is
// measured on one fault costs about 13 us (docs/accel/parallel-build.md, "Page faults"). Embree's allocator
// asks for huge pages the same way (madvise on Linux).
#pragma once

#include <cstddef>
#include <memory>
#include <new>
#include <vector>

namespace lancer {

inline constexpr std::size_t kHugePageBytes = std::size_t{2} << 20;

// Asks the kernel to back the whole 2 MiB pages inside [data, data + bytes) with huge pages when they are
// first touched; does nothing for a range that holds no whole huge page, or where the system has no such
// request (not Linux, or transparent huge pages off). Memory already touched keeps its pages.
void advise_huge_pages(const void* data, std::size_t bytes);

// v.reserve(count), the new storage advised into huge pages before anything touches it: for the large
// arrays whose public type is a plain std::vector (a TriangleMesh's positions and indices).
template <class T, class Allocator>
void reserve_huge_pages(std::vector<T, Allocator>& v, std::size_t count) {
    v.reserve(count);
    advise_huge_pages(v.data(), v.capacity() * sizeof(T));
}

// Writes one byte of every 4 KiB page of [data, data + bytes), the pages spread over the build's threads: a
// vector's constructor or resize() writes its elements on the calling thread alone, and would take every
// first-touch fault of a large array there (docs/accel/parallel-build.md, "Faults taken in parallel"). The
// bytes' values are left unspecified: for storage whose elements are yet to be constructed.
void touch_pages(void* data, std::size_t bytes);

// Storage of `bytes` that starts on a 2 MiB boundary, advised into huge pages to the end of its last one and
// touched, at the price of less than one huge page past `bytes`. Freed by deallocate_huge_pages with the same
// `bytes`.
[[nodiscard]] void* allocate_huge_pages(std::size_t bytes);
void deallocate_huge_pages(void* memory, std::size_t bytes) noexcept;

// Storage of two huge pages or more is allocate_huge_pages': every page of it is then a huge page. A plain
// allocation starts anywhere, and its first and last partial 2 MiB stay in 4 KiB pages, each faulted on its
// first touch. Smaller storage is std::allocator's: glibc hands it back to a later build from its heap,
// already faulted, where it maps an aligned request (the size plus 2 MiB) of one to two huge pages afresh
// every time (docs/accel/parallel-build.md, "The structures' own arrays in huge pages"). Of that, storage of
// kTouchedBytes or more is touched in parallel too.
template <class T>
struct HugePageAllocator {
    using value_type = T;
    static constexpr std::size_t kMinBytes = 2 * kHugePageBytes;
    static constexpr std::size_t kTouchedBytes = std::size_t{1} << 20;

    HugePageAllocator() = default;
    template <class U>
    HugePageAllocator(const HugePageAllocator<U>& /*other*/) {}  // NOLINT(google-explicit-constructor)

    [[nodiscard]] static constexpr bool in_huge_pages(std::size_t count) {
        return count * sizeof(T) >= kMinBytes;
    }
    [[nodiscard]] T* allocate(std::size_t count) {
        if (in_huge_pages(count)) return static_cast<T*>(allocate_huge_pages(count * sizeof(T)));
        T* memory = std::allocator<T>().allocate(count);
        if (count * sizeof(T) >= kTouchedBytes) touch_pages(memory, count * sizeof(T));
        return memory;
    }
    void deallocate(T* memory, std::size_t count) {
        if (!in_huge_pages(count)) return std::allocator<T>().deallocate(memory, count);
        deallocate_huge_pages(memory, count * sizeof(T));
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
