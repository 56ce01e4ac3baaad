// What the per-ray traversals of src/cuda/ share so that one source runs on the GPU (nvcc) and on the CPU
// (g++, where tests/cuda checks it against the CPU structures): the LANCER_HOST_DEVICE marker and the few
// scalar helpers the traversals need, written to round and order exactly as the CPU code they port.
#pragma once

#include <cstdint>
#include <cstring>

#include "core/host_device.hpp"
#include "lancer/ray.hpp"
#include "lancer/vec.hpp"

namespace lancer::gpu {

// std::min and std::max, NaN operand order included: min_of(a, b) is a unless b < a (fminf would drop a
// NaN instead, and the slab tests rely on std::min's order).
LANCER_HOST_DEVICE inline float min_of(float a, float b) {
    return b < a ? b : a;
}
LANCER_HOST_DEVICE inline float max_of(float a, float b) {
    return a < b ? b : a;
}
LANCER_HOST_DEVICE inline std::uint32_t min_of(std::uint32_t a, std::uint32_t b) {
    return b < a ? b : a;
}
LANCER_HOST_DEVICE inline float abs_of(float a) {
    return a < 0.0f ? -a : (a == 0.0f ? 0.0f : a);
}
LANCER_HOST_DEVICE inline bool is_nan(float a) {
    return a != a;
}
LANCER_HOST_DEVICE inline Vec3f abs_of(const Vec3f& a) {
    return {abs_of(a.x), abs_of(a.y), abs_of(a.z)};
}

// The rounding bound gamma(n) of core/intersect.hpp, as a constant (constexpr host code is not callable on
// the device without --expt-relaxed-constexpr; the tests compare the two).
inline constexpr float kHalfUlp = 0x1p-24f;
LANCER_HOST_DEVICE inline float gamma_of(int n) {
    return (static_cast<float>(n) * kHalfUlp) / (1.0f - static_cast<float>(n) * kHalfUlp);
}

// widened_slab_exit of core/intersect.hpp: the exit moved away from the entry by 2 gamma(3) of its magnitude,
// towards +inf whatever its sign.
LANCER_HOST_DEVICE inline float widened_exit(float t) {
    return t * (t > 0.0f ? 1.0f + 2.0f * gamma_of(3) : 1.0f - 2.0f * gamma_of(3));
}

// 2^-level, exactly (OctreeCube::kInversePowersOfTwo[level]), from its bits rather than a table: the walk
// reads it at a per-lane level, and a constant-memory table is served one address at a time.
LANCER_HOST_DEVICE inline float inverse_power_of_two(int level) {
    const auto bits = static_cast<std::uint32_t>(127 - level) << 23;
    float power;
    std::memcpy(&power, &bits, sizeof(power));
    return power;
}

// closer() of lancer/ray.hpp: the smaller t, then the smaller primitive index.
LANCER_HOST_DEVICE inline bool is_closer(float t, std::int32_t prim, const Hit& best) {
    return t < best.t || (t == best.t && prim < best.prim);
}

// Loads through the read-only data cache on the device (__ldg, seed 000 section 5.2: cells, triangles and
// boxes are never written during a frame); a plain load on the host.
template <class T>
LANCER_HOST_DEVICE inline T read_only(const T* address) {
#if defined(__CUDA_ARCH__)
    return __ldg(address);
#else
    return *address;
#endif
}

// Asks the L1 cache for the line at `address` without waiting for it (PTX prefetch.global.L1); nothing on
// the host.
LANCER_HOST_DEVICE inline void prefetch_line(const void* address) {
#if defined(__CUDA_ARCH__)
    asm volatile("prefetch.global.L1 [%0];" ::"l"(address));
#else
    (void)address;
#endif
}

// A record of whole 8-byte words (a 40-byte triangle, a 64-byte node) through the read-only cache, as
// float2 loads: the arrays come from cudaMalloc (256-byte aligned) and every record size is a multiple of 8.
template <class Record>
LANCER_HOST_DEVICE inline Record read_only_record(const Record* address) {
    static_assert(sizeof(Record) % 8 == 0);
#if defined(__CUDA_ARCH__)
    Record record;
    const float2* words = reinterpret_cast<const float2*>(address);
    float2 loaded[sizeof(Record) / 8];
#pragma unroll
    for (unsigned i = 0; i < sizeof(Record) / 8; ++i)
        loaded[i] = __ldg(words + i);
    memcpy(&record, loaded, sizeof(Record));
    return record;
#else
    Record record;
    std::memcpy(&record, address, sizeof(Record));
    return record;
#endif
}

}  // namespace lancer::gpu
