// LANCER_HOST_DEVICE marks a function that one source gives to both the CPU (g++) and the GPU (nvcc): the
// kernels CPU and GPU share are written once (docs/cuda.md).
#pragma once

#if defined(__CUDACC__)
#define LANCER_HOST_DEVICE __host__ __device__
#else
#define LANCER_HOST_DEVICE
#endif

#include <cmath>
#include <cstdint>
#include <cstring>

#include "lancer/vec.hpp"

namespace lancer {

// |x| on the CPU and the GPU alike (std::fabs is no device function): the sign bit cleared on both.
LANCER_HOST_DEVICE inline float magnitude(float x) {
#if defined(__CUDA_ARCH__)
    return fabsf(x);
#else
    return std::fabs(x);
#endif
}
LANCER_HOST_DEVICE inline double magnitude(double x) {
#if defined(__CUDA_ARCH__)
    return fabs(x);
#else
    return std::fabs(x);
#endif
}
LANCER_HOST_DEVICE inline Vec3f magnitude(const Vec3f& v) {
    return {magnitude(v.x), magnitude(v.y), magnitude(v.z)};
}

// std::min and std::max, NaN operand order included: min_of(a, b) is a unless b < a (fminf would drop a NaN
// instead, and the slab tests rely on std::min's order). Neither is a device function.
LANCER_HOST_DEVICE inline float min_of(float a, float b) {
    return b < a ? b : a;
}
LANCER_HOST_DEVICE inline float max_of(float a, float b) {
    return a < b ? b : a;
}
LANCER_HOST_DEVICE inline std::uint32_t min_of(std::uint32_t a, std::uint32_t b) {
    return b < a ? b : a;
}
LANCER_HOST_DEVICE inline bool is_nan(float a) {
    return a != a;
}

// a b - c d within 2 2^-24 of its magnitude, where the two rounded products and their difference err by up
// to 2^-24 (|a b| + |c d|) under cancellation: Kahan's algorithm, whose second fused multiply-add recovers
// the rounding error of c d exactly (Jeannerod, Louvet & Muller, "Further analysis of Kahan's algorithm for
// the accurate computation of 2 x 2 determinants", Math. Comp. 2013). Fused explicitly, so that the vector
// kernels (simd::*::difference_of_products) and the GPU give the same bits under -ffp-contract=off.
LANCER_HOST_DEVICE inline float difference_of_products(float a, float b, float c, float d) {
    const float cd = c * d;
#if defined(__CUDA_ARCH__)
    return __fmaf_rn(a, b, -cd) + __fmaf_rn(-c, d, cd);
#else
    return std::fma(a, b, -cd) + std::fma(-c, d, cd);
#endif
}

// 2^-level, exactly, from its bits rather than a table: a walk reads it at a per-lane level, and a
// constant-memory table is served one address at a time.
LANCER_HOST_DEVICE inline float inverse_power_of_two(int level) {
    const auto bits = static_cast<std::uint32_t>(127 - level) << 23;
    float power;
    std::memcpy(&power, &bits, sizeof(power));
    return power;
}

// Loads through the read-only data cache on the device (__ldg, Portalez & Duguet 2016, section 5.2: cells,
// triangles and boxes are never written during a frame); a plain load on the host.
template <class T>
LANCER_HOST_DEVICE inline T read_only(const T* address) {
#if defined(__CUDA_ARCH__)
    return __ldg(address);
#else
    return *address;
#endif
}

// Asks the cache for the line at `address` without waiting for it: PTX prefetch.global.L1 on the device,
// the compiler's prefetch on the host.
LANCER_HOST_DEVICE inline void prefetch_line(const void* address) {
#if defined(__CUDA_ARCH__)
    asm volatile("prefetch.global.L1 [%0];" ::"l"(address));
#else
    __builtin_prefetch(address);
#endif
}

}  // namespace lancer
