// CUDA runtime errors as CudaError, naming the call that failed.
#pragma once

#include <cuda_runtime_api.h>

#include <string>

#include "lancer/cuda.hpp"

namespace lancer::gpu {

inline void check_cuda(cudaError_t status, const char* call) {
    if (status != cudaSuccess) throw CudaError(std::string(call) + ": " + cudaGetErrorString(status));
}

}  // namespace lancer::gpu
