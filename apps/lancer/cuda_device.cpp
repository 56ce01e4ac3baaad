#include "cuda_device.hpp"

#include <stdexcept>

namespace lancer::cli {

void DeviceChoice::add_options(CLI::App& command) {
    command.add_option("--device", device, "Where to trace: cpu, or cuda (an NVIDIA GPU; docs/cuda.md)")
        ->transform(one_of(std::vector<std::string>{"cpu", "cuda"}))
        ->capture_default_str();
    std::vector<std::string> kernels;
    for (const CudaKernel each :
         {CudaKernel::Plucker, CudaKernel::WhileWhile, CudaKernel::SpeculativeWhileWhile,
          CudaKernel::Persistent, CudaKernel::CompressedWide})
        kernels.emplace_back(cuda_kernel_name(each));
    command
        .add_option("--cuda-kernel", kernel,
                    "With --device cuda: plucker, while-while, speculative, persistent or cwbvh (default: "
                    "plucker for --accel plucker, persistent for bvh, cwbvh for bvh8)")
        ->transform(one_of(kernels));
}

void DeviceChoice::require_available() const {
    std::string why;
    if (cuda() && !cuda_available(&why)) throw InputError("--device cuda: " + why);
}

CudaKernel DeviceChoice::kernel_for(std::string_view accel_name) const {
    try {
        const CudaKernel fallback = default_cuda_kernel(accel_name);
        if (kernel.empty()) return fallback;
        const CudaKernel chosen = parse_cuda_kernel(kernel);
        if (cuda_kernel_structure(chosen) != cuda_kernel_structure(fallback)) {
            throw std::invalid_argument("--cuda-kernel " + kernel + " does not trace --accel " +
                                        std::string(accel_name));
        }
        return chosen;
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    }
}

std::unique_ptr<CudaTracer> make_cuda_tracer(const DeviceChoice& device, TriangleTest triangle_test,
                                             const Accel& accel, const Geometry& geometry) {
    const CudaKernel kernel = device.kernel_for(accel.name());
    try {
        return std::make_unique<CudaTracer>(accel, geometry, triangle_test, kernel);
    } catch (const CudaError& error) {
        throw InputError(std::string("--device cuda: ") + error.what());
    } catch (const std::invalid_argument& error) {
        throw InputError(std::string("--device cuda: ") + error.what());
    }
}

}  // namespace lancer::cli
