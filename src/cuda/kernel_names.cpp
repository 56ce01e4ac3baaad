#include <iterator>
#include <stdexcept>
#include <string>

#include "lancer/cuda.hpp"

namespace lancer {

namespace {
constexpr std::string_view kNames[] = {"plucker", "while-while", "speculative", "persistent", "cwbvh"};
constexpr int kKernelCount = static_cast<int>(std::size(kNames));
}  // namespace

std::string_view cuda_kernel_name(CudaKernel kernel) {
    return kNames[static_cast<int>(kernel)];
}

CudaKernel parse_cuda_kernel(std::string_view name) {
    for (int i = 0; i < kKernelCount; ++i)
        if (kNames[i] == name) return static_cast<CudaKernel>(i);
    throw std::invalid_argument("unknown CUDA kernel '" + std::string(name) +
                                "': expected plucker, while-while, speculative, persistent or cwbvh");
}

std::string_view cuda_kernel_structure(CudaKernel kernel) {
    switch (kernel) {
        case CudaKernel::Plucker:
            return "plucker";
        case CudaKernel::CompressedWide:
            return "bvh8";
        case CudaKernel::WhileWhile:
        case CudaKernel::SpeculativeWhileWhile:
        case CudaKernel::Persistent:
            break;
    }
    return "bvh";
}

CudaKernel default_cuda_kernel(std::string_view accel_name) {
    if (accel_name == "plucker") return CudaKernel::Plucker;
    if (accel_name == "bvh") return CudaKernel::Persistent;
    if (accel_name == "bvh8") return CudaKernel::CompressedWide;
    throw std::invalid_argument("--device cuda traces --accel plucker, bvh or bvh8, not '" +
                                std::string(accel_name) + "'");
}

}  // namespace lancer
