#include <stdexcept>
#include <string>

#include "lancer/cuda.hpp"

namespace lancer {

namespace {
constexpr std::string_view kNames[] = {"plucker", "while-while", "speculative", "persistent"};
}  // namespace

std::string_view cuda_kernel_name(CudaKernel kernel) {
    return kNames[static_cast<int>(kernel)];
}

CudaKernel parse_cuda_kernel(std::string_view name) {
    for (int i = 0; i < 4; ++i)
        if (kNames[i] == name) return static_cast<CudaKernel>(i);
    throw std::invalid_argument("unknown CUDA kernel '" + std::string(name) +
                                "': expected plucker, while-while, speculative or persistent");
}

CudaKernel default_cuda_kernel(std::string_view accel_name) {
    if (accel_name == "plucker") return CudaKernel::Plucker;
    if (accel_name == "bvh") return CudaKernel::Persistent;
    throw std::invalid_argument("--device cuda traces --accel plucker or bvh, not '" +
                                std::string(accel_name) + "'");
}

}  // namespace lancer
