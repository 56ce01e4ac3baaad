// LANCER_HOST_DEVICE marks a function that one source gives to both the CPU (g++) and the GPU (nvcc): the
// kernels CPU and GPU share are written once (docs/cuda.md).
#pragma once

#if defined(__CUDACC__)
#define LANCER_HOST_DEVICE __host__ __device__
#else
#define LANCER_HOST_DEVICE
#endif

#include <cmath>

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
LANCER_HOST_DEVICE inline Vec3f magnitude(const Vec3f& v) {
    return {magnitude(v.x), magnitude(v.y), magnitude(v.z)};
}

}  // namespace lancer
