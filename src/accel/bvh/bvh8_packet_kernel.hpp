// The entry points of bvh8_packet's kernel (bvh8_packet_kernel.cpp), one table per instruction set it is
// compiled for, so that Bvh8PacketAccel chooses at run time (lancer/isa.hpp) and the library's baseline
// stays AVX2.
#pragma once

#include <cstdint>
#include <span>

#include "accel/bvh/bvh_wide.hpp"
#include "core/isa_namespace.hpp"
#include "lancer/accel.hpp"

namespace lancer {

// Rays traced together: one 8x8 tile of `lancer bench`, and the 64 bits of a lane mask.
inline constexpr int kBvh8PacketSize = 64;
static_assert(kBvh8PacketSize == RayPacket::kMaxSize, "a RayPacket is traced as one packet");

// The ray streams that walk at once, a node of each in turn, on a tree larger than the caches (of 2, 4, 8,
// 12 and 16, 8 measured best: docs/accel/stream.md, "Streams in flight").
inline constexpr int kStreamsInFlight = 8;

// What a batch call needs besides its rays: the tree, the geometry and triangle test it was built with, the
// scale of a coherent packet's width (the mean diagonal of the tree's leaf boxes) and the ray streams that
// walk at once: 1, or kStreamsInFlight (bvh.interleaved_streams) (docs/accel/stream.md).
struct Bvh8PacketTarget {
    const Bvh8Accel& bvh;
    const Geometry& geometry;
    TriangleTest test;
    float coherent_width;
    int streams_in_flight;
};

struct Bvh8PacketKernels {
    int lane_count;  // rays per instruction of the box and triangle tests
    void (*intersect)(const Bvh8PacketTarget& target, std::span<const Ray> rays, std::span<Hit> hits,
                      TraversalCounters* counters);
    void (*occluded)(const Bvh8PacketTarget& target, std::span<const Ray> rays,
                     std::span<std::uint8_t> occluded, TraversalCounters* counters);
    void (*intersect_packet)(const Bvh8PacketTarget& target, const RayPacket& rays, HitPacket& hits,
                             TraversalCounters* counters);
};

// Each compilation's table in its instruction set's namespace (core/isa_namespace.hpp). The namespace of the
// compilation including this header is inline there, and is reopened as inline here (clang warns otherwise).
#if defined(__AVX2__)
#if !defined(LANCER_KERNEL_AVX512)
inline
#endif
    namespace avx2 {
[[nodiscard]] const Bvh8PacketKernels& bvh8_packet_kernels();
}  // namespace avx2
#endif
#if LANCER_HAS_AVX512_KERNELS
#if defined(LANCER_KERNEL_AVX512)
inline
#endif
    namespace avx512 {
[[nodiscard]] const Bvh8PacketKernels& bvh8_packet_kernels();
}  // namespace avx512
#endif

}  // namespace lancer
