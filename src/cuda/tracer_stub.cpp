// CudaTracer in a build without LANCER_CUDA: every entry point says so.
#include "lancer/cuda.hpp"

namespace lancer {

namespace {
constexpr const char* kWithoutCuda = "built without CUDA (configure with -DLANCER_CUDA=ON and nvcc)";
}  // namespace

bool cuda_available(std::string* why) {
    if (why) *why = kWithoutCuda;
    return false;
}

struct CudaTracer::Impl {};

CudaTracer::CudaTracer(const Accel&, const Geometry&, TriangleTest, CudaKernel) {
    throw CudaError(kWithoutCuda);
}
CudaTracer::~CudaTracer() = default;
CudaTrace CudaTracer::trace_frame(const Camera&, bool) {
    throw CudaError(kWithoutCuda);
}
CudaTrace CudaTracer::trace(std::span<const Ray>) {
    throw CudaError(kWithoutCuda);
}
CudaTrace CudaTracer::occluded(std::span<const Ray>) {
    throw CudaError(kWithoutCuda);
}
void CudaTracer::upload_rays(std::span<const Ray>) {
    throw CudaError(kWithoutCuda);
}
CudaTrace CudaTracer::trace_uploaded(bool) {
    throw CudaError(kWithoutCuda);
}
std::string CudaTracer::device_name() const {
    throw CudaError(kWithoutCuda);
}

}  // namespace lancer
