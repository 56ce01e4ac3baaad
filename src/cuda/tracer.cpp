// CudaTracer with LANCER_CUDA: the arrays uploaded once (cudaMalloc, cudaMemcpy), the kernels launched by
// kernels.cu, the hits copied back. Plain C++ over the CUDA runtime API.
#include <cuda_runtime_api.h>

#include <stdexcept>
#include <utility>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/plucker/plucker.hpp"
#include "core/ray_conditioning.hpp"
#include "cuda/cuda_check.hpp"
#include "cuda/cwbvh_build.hpp"
#include "cuda/flatten.hpp"
#include "cuda/kernels.hpp"
#include "lancer/camera.hpp"
#include "lancer/cuda.hpp"

namespace lancer {
namespace {

// One device allocation, freed with its owner.
class DeviceBuffer {
  public:
    DeviceBuffer() = default;
    DeviceBuffer(const DeviceBuffer&) = delete;
    DeviceBuffer& operator=(const DeviceBuffer&) = delete;
    ~DeviceBuffer() {
        if (data_ != nullptr) cudaFree(data_);
    }

    // At least `bytes` (one byte for an empty array, so that every view's pointer is valid).
    void reserve(std::size_t bytes) {
        if (bytes <= bytes_ && data_ != nullptr) return;
        if (data_ != nullptr) cudaFree(std::exchange(data_, nullptr));
        gpu::check_cuda(cudaMalloc(&data_, bytes == 0 ? 1 : bytes), "cudaMalloc");
        bytes_ = bytes;
    }
    template <class T>
    [[nodiscard]] T* upload(const std::vector<T>& values) {
        reserve(values.size() * sizeof(T));
        gpu::check_cuda(cudaMemcpy(data_, values.data(), values.size() * sizeof(T), cudaMemcpyHostToDevice),
                        "cudaMemcpy (upload)");
        return static_cast<T*>(data_);
    }
    template <class T>
    [[nodiscard]] T* as() const {
        return static_cast<T*>(data_);
    }

  private:
    void* data_ = nullptr;
    std::size_t bytes_ = 0;
};

}  // namespace

bool cuda_available(std::string* why) {
    int count = 0;
    const cudaError_t status = cudaGetDeviceCount(&count);
    if (status != cudaSuccess) {
        if (why)
            *why = std::string("no CUDA device (cudaGetDeviceCount: ") + cudaGetErrorString(status) + ")";
        return false;
    }
    if (count == 0) {
        if (why) *why = "no CUDA device (cudaGetDeviceCount: 0 devices)";
        return false;
    }
    return true;
}

struct CudaTracer::Impl {
    CudaKernel kernel;
    // The structure's box in the caller's units and the scale at which it sees the scene (Accel::bounds,
    // built_geometry): rays are conditioned as on the CPU.
    Box3f bounds;
    int scale_exponent = 0;
    gpu::LaunchScene scene;
    DeviceBuffer nodes, triangles, cells, primitives, boxes, texels, locate;  // the structure, uploaded once
    DeviceBuffer rays, hits, occluded, steps, next_ray;                       // per call, grown as needed
    // The uploaded batch: its size, and what maps its conditioned hits back (restore_hits): the rays as
    // the caller gave them, kept only when conditioning changed some.
    std::size_t uploaded_count = 0;
    bool uploaded = false;
    ConditionedRays conditioned;
    std::vector<Ray> original_rays;

    // The uploaded batch's closest hits (count_steps: with each ray's steps) or occlusion, t mapped back to
    // the caller's rays. Occlusion maps nothing back: conditioning keeps each ray's interval
    // (scaled_interval).
    CudaTrace trace_uploaded(bool any_hit, bool count_steps) {
        if (!uploaded) throw std::logic_error("cuda: trace_uploaded before upload_rays");
        gpu::LaunchRays launch;
        launch.rays = rays.as<Ray>();
        launch.count = static_cast<std::uint32_t>(uploaded_count);
        CudaTrace result = run(launch, uploaded_count, any_hit, count_steps);
        if (!any_hit && !original_rays.empty()) restore_hits(conditioned, original_rays, result.hits);
        return result;
    }

    // A frame or a batch (count_steps: with each ray's steps), closest hits or occlusion.
    CudaTrace run(const gpu::LaunchRays& launch, std::size_t ray_count, bool any_hit, bool count_steps) {
        CudaTrace result;
        if (ray_count == 0) return result;  // a grid of no blocks is a launch error
        gpu::LaunchAnswers answers;
        if (any_hit) {
            occluded.reserve(ray_count);
            answers.occluded = occluded.as<std::uint8_t>();
        } else {
            hits.reserve(ray_count * sizeof(Hit));
            answers.hits = hits.as<Hit>();
        }
        if (count_steps) {
            steps.reserve(ray_count * sizeof(std::uint32_t));
            answers.steps = steps.as<std::uint32_t>();
        }
        next_ray.reserve(sizeof(std::uint32_t));
        result.kernel_ms = gpu::launch_trace(kernel, scene, launch, answers, next_ray.as<std::uint32_t>());
        if (any_hit) {
            result.occluded.resize(ray_count);
            gpu::check_cuda(
                cudaMemcpy(result.occluded.data(), answers.occluded, ray_count, cudaMemcpyDeviceToHost),
                "cudaMemcpy (occlusion)");
        } else {
            result.hits.resize(ray_count);
            gpu::check_cuda(
                cudaMemcpy(result.hits.data(), answers.hits, ray_count * sizeof(Hit), cudaMemcpyDeviceToHost),
                "cudaMemcpy (hits)");
        }
        if (count_steps) {
            result.steps.resize(ray_count);
            gpu::check_cuda(cudaMemcpy(result.steps.data(), answers.steps, ray_count * sizeof(std::uint32_t),
                                       cudaMemcpyDeviceToHost),
                            "cudaMemcpy (steps)");
        }
        return result;
    }
};

CudaTracer::CudaTracer(const Accel& accel, const Geometry& /*geometry: accel's*/, TriangleTest test,
                       CudaKernel kernel)
    : impl_(std::make_unique<Impl>()) {
    std::string why;
    if (!cuda_available(&why)) throw CudaError(why);
    impl_->kernel = kernel;
    impl_->bounds = accel.bounds();
    impl_->scale_exponent = accel.scale_exponent();
    impl_->scene.watertight = test == TriangleTest::Watertight;
    const ExportedLayout exported = accel.exported_layout();
    if (kernel == CudaKernel::Plucker) {
        if (exported.plucker == nullptr)
            throw std::invalid_argument(
                "cuda: the plucker kernel traces a `plucker` or `plucker_packet` structure");
        const plucker::PluckerLayout& layout = *exported.plucker;
        plucker::PluckerView view = gpu::plucker_view(layout);  // checks the primitives
        view.cells = impl_->cells.upload(layout.cells);
        view.primitives = impl_->primitives.upload(layout.primitives);
        view.boxes = impl_->boxes.upload(layout.boxes);
        view.texels = impl_->texels.upload(layout.cube_map.texels);
        view.locate = impl_->locate.upload(layout.locate);
        impl_->scene.plucker = view;
        gpu::upload_plucker_tables(plucker::kTables);
        return;
    }
    if (kernel == CudaKernel::CompressedWide) {
        // A packet structure traces its single-ray structure's tree: that tree is the one to convert.
        const Accel& tree = exported.single_ray != nullptr ? *exported.single_ray : accel;
        const auto* bvh8 = dynamic_cast<const Bvh8Accel*>(&tree);
        if (bvh8 == nullptr)
            throw std::invalid_argument("cuda: the cwbvh kernel traces a `bvh8` or `bvh8_packet` structure");
        const gpu::CompressedWideBvh compressed = gpu::compress_bvh8(*bvh8, bvh8->built_geometry());
        impl_->scene.cwbvh = {impl_->nodes.upload(compressed.nodes),
                              static_cast<std::uint32_t>(compressed.nodes.size()),
                              impl_->triangles.upload(compressed.triangles)};
        return;
    }
    if (exported.bvh == nullptr)
        throw std::invalid_argument("cuda: the " + std::string(cuda_kernel_name(kernel)) +
                                    " kernel traces a `bvh` or `bvh_packet` structure");
    // The triangles the tree was built on: the caller's geometry, or its copy at the structure's scale.
    const gpu::FlatBvh flat = gpu::flatten_bvh(*exported.bvh, accel.built_geometry());
    impl_->scene.bvh = {impl_->nodes.upload(flat.nodes), static_cast<std::uint32_t>(flat.nodes.size()),
                        impl_->triangles.upload(flat.triangles)};
}

CudaTracer::~CudaTracer() = default;

CudaTrace CudaTracer::trace_frame(const Camera& camera, bool count_steps) {
    const std::size_t ray_count =
        static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height);
    // A camera far from the scene, or any camera of a scene the structure sees scaled: its rays are made here
    // and conditioned like the CPU's (Accel::intersect; src/core/ray_conditioning.hpp), so that both answer
    // them alike. Camera directions are ordinary.
    if (impl_->scale_exponent != 0 || FarOriginFrame(impl_->bounds).is_far(camera.eye)) {
        upload_rays(PinholeCamera(camera).pixel_centre_rays(0, 0, camera.width, camera.height));
        return impl_->trace_uploaded(false, count_steps);
    }
    gpu::LaunchRays launch;
    launch.camera = PinholeCamera(camera).frame();
    return impl_->run(launch, ray_count, false, count_steps);
}

CudaTrace CudaTracer::trace(std::span<const Ray> rays) {
    upload_rays(rays);
    return trace_uploaded(false);
}

CudaTrace CudaTracer::occluded(std::span<const Ray> rays) {
    upload_rays(rays);
    return trace_uploaded(true);
}

void CudaTracer::upload_rays(std::span<const Ray> rays) {
    if (rays.size() >= (1u << 31)) throw std::invalid_argument("cuda: at most 2^31 rays per batch");
    impl_->uploaded = false;
    impl_->conditioned = condition_rays(rays, impl_->bounds, impl_->scale_exponent);
    const bool changed = !impl_->conditioned.rays.empty();
    impl_->original_rays.clear();
    if (changed) impl_->original_rays.assign(rays.begin(), rays.end());
    const std::span<const Ray> traced = changed ? std::span<const Ray>(impl_->conditioned.rays) : rays;
    impl_->rays.reserve(rays.size() * sizeof(Ray));
    gpu::check_cuda(
        cudaMemcpy(impl_->rays.as<Ray>(), traced.data(), traced.size() * sizeof(Ray), cudaMemcpyHostToDevice),
        "cudaMemcpy (rays)");
    impl_->uploaded_count = rays.size();
    impl_->uploaded = true;
}

CudaTrace CudaTracer::trace_uploaded(bool any_hit) {
    return impl_->trace_uploaded(any_hit, false);
}

std::string CudaTracer::device_name() const {
    int device = 0;
    cudaDeviceProp properties{};
    gpu::check_cuda(cudaGetDevice(&device), "cudaGetDevice");
    gpu::check_cuda(cudaGetDeviceProperties(&properties, device), "cudaGetDeviceProperties");
    return properties.name;
}

}  // namespace lancer
