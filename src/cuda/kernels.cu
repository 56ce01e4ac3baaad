// The kernels: thin wrappers that make each thread's ray (the canonical camera's, or one of a batch), call
// the per-ray traversal of bvh_traversal.hpp, cwbvh_traversal.hpp or plucker_walk.hpp, and store the hit or
// the occlusion byte. Persistent threads (Aila & Laine 2009, section 3.3) fetch warp-sized batches of ray
// indices from a global counter until the rays run out, so that no warp waits on the slowest warp of its
// block.
#include <cuda_runtime.h>

#include "cuda/bvh_traversal.hpp"
#include "cuda/cuda_check.hpp"
#include "cuda/cwbvh_traversal.hpp"
#include "cuda/kernels.hpp"
#include "cuda/plucker_walk.hpp"

namespace lancer::gpu {
namespace {

constexpr unsigned kBlockSize = 128;
constexpr unsigned kWarpSize = 32;

// Portalez & Duguet 2016, section 5.2: the lookup tables in constant memory.
__constant__ plucker::PluckerTables c_tables;

// The speculative traversal's vote over the lanes still in the loop.
struct WarpVote {
    LANCER_HOST_DEVICE bool any_searching(bool searching) const {
#if defined(__CUDA_ARCH__)
        return __any_sync(__activemask(), searching);
#else
        return searching;
#endif
    }
};

struct CameraRays {
    CameraFrame camera;
    __device__ bool get(std::uint32_t index, Ray& ray, std::uint32_t& slot) const {
        int x, y;
        if (!frame_pixel(camera, index, x, y)) return false;
        ray = camera_ray(camera, static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
        slot = static_cast<std::uint32_t>(y) * static_cast<std::uint32_t>(camera.width) +
               static_cast<std::uint32_t>(x);
        return true;
    }
};

struct BatchRays {
    const Ray* rays;
    std::uint32_t count;
    __device__ bool get(std::uint32_t index, Ray& ray, std::uint32_t& slot) const {
        if (index >= count) return false;
        ray = read_only_record(rays + index);
        slot = index;
        return true;
    }
};

// Layout: the walk's WalkLayout (the octree's variant); the BVH kernels ignore it.
template <CudaKernel kKernel, class TriangleTestT, bool kAnyHit, class Layout, class Steps>
__device__ Hit trace_one(const LaunchScene& scene, const Ray& ray, Steps& steps) {
    if constexpr (kKernel == CudaKernel::Plucker) {
        return trace_plucker<TriangleTestT, Layout, kAnyHit>(scene.plucker, c_tables, ray, steps);
    } else if constexpr (kKernel == CudaKernel::CompressedWide) {
        return trace_cwbvh<kAnyHit, TriangleTestT>(scene.cwbvh, ray, steps);
    } else if constexpr (kKernel == CudaKernel::WhileWhile) {
        return trace_bvh<false, TriangleTestT, kAnyHit>(scene.bvh, ray, WarpVote{}, steps);
    } else {
        return trace_bvh<true, TriangleTestT, kAnyHit>(scene.bvh, ray, WarpVote{}, steps);
    }
}

// What a kernel computes and stores for a ray: its closest hit, with its step count too (the heatmap), or
// one occlusion byte.
enum class Query { ClosestHit, ClosestHitCounted, AnyHit };

template <CudaKernel kKernel, class TriangleTestT, Query kQuery, class Layout = SeedLayout>
__device__ void trace_and_store(const LaunchScene& scene, const Ray& ray, std::uint32_t slot,
                                const LaunchAnswers& answers) {
    if constexpr (kQuery == Query::ClosestHitCounted) {
        CountSteps counted;
        answers.hits[slot] = trace_one<kKernel, TriangleTestT, false, Layout>(scene, ray, counted);
        answers.steps[slot] = counted.steps;
    } else if constexpr (kQuery == Query::AnyHit) {
        NoSteps none;
        answers.occluded[slot] = trace_one<kKernel, TriangleTestT, true, Layout>(scene, ray, none).prim >= 0;
    } else {
        NoSteps none;
        answers.hits[slot] = trace_one<kKernel, TriangleTestT, false, Layout>(scene, ray, none);
    }
}

// One thread per ray.
template <CudaKernel kKernel, class TriangleTestT, Query kQuery, class Source, class Layout = SeedLayout>
__global__ void __launch_bounds__(kBlockSize)
    trace_kernel(LaunchScene scene, Source source, LaunchAnswers answers) {
    const std::uint32_t index = blockIdx.x * blockDim.x + threadIdx.x;
    Ray ray;
    std::uint32_t slot;
    if (source.get(index, ray, slot))
        trace_and_store<kKernel, TriangleTestT, kQuery, Layout>(scene, ray, slot, answers);
}

// Persistent threads: as many warps as fit on the GPU at once; lane 0 takes the next 32 ray indices and
// hands them to the warp, until none are left.
template <class TriangleTestT, Query kQuery, class Source>
__global__ void __launch_bounds__(kBlockSize)
    persistent_kernel(LaunchScene scene, Source source, std::uint32_t count, LaunchAnswers answers,
                      std::uint32_t* next_ray) {
    const unsigned lane = threadIdx.x % kWarpSize;
    while (true) {
        std::uint32_t base = 0;
        if (lane == 0) base = atomicAdd(next_ray, kWarpSize);
        base = __shfl_sync(0xFFFFFFFFu, base, 0);
        if (base >= count) return;
        Ray ray;
        std::uint32_t slot;
        if (source.get(base + lane, ray, slot))
            trace_and_store<CudaKernel::SpeculativeWhileWhile, TriangleTestT, kQuery>(scene, ray, slot,
                                                                                      answers);
    }
}

// The walk compiled for the octree's layout.
template <class TriangleTestT, Query kQuery, class Source>
void launch_walk(unsigned blocks, const LaunchScene& scene, const Source& source,
                 const LaunchAnswers& answers) {
    const plucker::PluckerView& octree = scene.plucker;
    if (octree.balanced && octree.stored_boxes)
        trace_kernel<CudaKernel::Plucker, TriangleTestT, kQuery, Source, WalkLayout<true, true>>
            <<<blocks, kBlockSize>>>(scene, source, answers);
    else if (octree.balanced)
        trace_kernel<CudaKernel::Plucker, TriangleTestT, kQuery, Source, WalkLayout<true, false>>
            <<<blocks, kBlockSize>>>(scene, source, answers);
    else if (octree.stored_boxes)
        trace_kernel<CudaKernel::Plucker, TriangleTestT, kQuery, Source, WalkLayout<false, true>>
            <<<blocks, kBlockSize>>>(scene, source, answers);
    else
        trace_kernel<CudaKernel::Plucker, TriangleTestT, kQuery, Source, WalkLayout<false, false>>
            <<<blocks, kBlockSize>>>(scene, source, answers);
}

template <class TriangleTestT, Query kQuery, class Source>
void launch(CudaKernel kernel, const LaunchScene& scene, const Source& source, std::uint32_t count,
            const LaunchAnswers& answers, std::uint32_t* next_ray) {
    const unsigned blocks = (count + kBlockSize - 1) / kBlockSize;
    switch (kernel) {
        case CudaKernel::Plucker:
            launch_walk<TriangleTestT, kQuery>(blocks, scene, source, answers);
            break;
        case CudaKernel::CompressedWide:
            trace_kernel<CudaKernel::CompressedWide, TriangleTestT, kQuery>
                <<<blocks, kBlockSize>>>(scene, source, answers);
            break;
        case CudaKernel::WhileWhile:
            trace_kernel<CudaKernel::WhileWhile, TriangleTestT, kQuery>
                <<<blocks, kBlockSize>>>(scene, source, answers);
            break;
        case CudaKernel::SpeculativeWhileWhile:
            trace_kernel<CudaKernel::SpeculativeWhileWhile, TriangleTestT, kQuery>
                <<<blocks, kBlockSize>>>(scene, source, answers);
            break;
        case CudaKernel::Persistent: {
            const auto persistent = persistent_kernel<TriangleTestT, kQuery, Source>;
            int device = 0, multiprocessors = 0, blocks_per_multiprocessor = 0;
            check_cuda(cudaGetDevice(&device), "cudaGetDevice");
            check_cuda(cudaDeviceGetAttribute(&multiprocessors, cudaDevAttrMultiProcessorCount, device),
                       "cudaDeviceGetAttribute");
            check_cuda(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&blocks_per_multiprocessor, persistent,
                                                                     kBlockSize, 0),
                       "cudaOccupancyMaxActiveBlocksPerMultiprocessor");
            check_cuda(cudaMemset(next_ray, 0, sizeof(std::uint32_t)), "cudaMemset");
            const auto resident = static_cast<unsigned>(multiprocessors * blocks_per_multiprocessor);
            const unsigned persistent_blocks = resident < blocks ? resident : blocks;
            persistent<<<persistent_blocks, kBlockSize>>>(scene, source, count, answers, next_ray);
            break;
        }
    }
    check_cuda(cudaGetLastError(), "kernel launch");
}

// The query's kernels for the scene's triangle test. Steps are counted for the heatmap, whose frame is a
// batch made on the host when the camera is far or the scene scaled (CudaTracer::trace_frame); only
// batches answer any-hit queries (the shadow view, the renderer's shadow rays).
template <Query kQuery, class Source>
void launch_test(CudaKernel kernel, const LaunchScene& scene, const Source& source, std::uint32_t count,
                 const LaunchAnswers& answers, std::uint32_t* next_ray) {
    if (scene.watertight)
        launch<Watertight, kQuery>(kernel, scene, source, count, answers, next_ray);
    else
        launch<MollerTrumbore, kQuery>(kernel, scene, source, count, answers, next_ray);
}

}  // namespace

void upload_plucker_tables(const plucker::PluckerTables& tables) {
    check_cuda(cudaMemcpyToSymbol(c_tables, &tables, sizeof(plucker::PluckerTables)), "cudaMemcpyToSymbol");
}

float launch_trace(CudaKernel kernel, const LaunchScene& scene, const LaunchRays& rays,
                   const LaunchAnswers& answers, std::uint32_t* next_ray) {
    cudaEvent_t start, stop;
    check_cuda(cudaEventCreate(&start), "cudaEventCreate");
    check_cuda(cudaEventCreate(&stop), "cudaEventCreate");
    check_cuda(cudaEventRecord(start), "cudaEventRecord");
    const std::uint32_t frame_rays = frame_ray_count(rays.camera);
    const BatchRays batch{rays.rays, rays.count};
    const CameraRays frame{rays.camera};
    if (rays.rays != nullptr && answers.occluded != nullptr)
        launch_test<Query::AnyHit>(kernel, scene, batch, rays.count, answers, next_ray);
    else if (rays.rays != nullptr && answers.steps != nullptr)
        launch_test<Query::ClosestHitCounted>(kernel, scene, batch, rays.count, answers, next_ray);
    else if (rays.rays != nullptr)
        launch_test<Query::ClosestHit>(kernel, scene, batch, rays.count, answers, next_ray);
    else if (answers.steps != nullptr)
        launch_test<Query::ClosestHitCounted>(kernel, scene, frame, frame_rays, answers, next_ray);
    else
        launch_test<Query::ClosestHit>(kernel, scene, frame, frame_rays, answers, next_ray);
    check_cuda(cudaEventRecord(stop), "cudaEventRecord");
    check_cuda(cudaEventSynchronize(stop), "cudaEventSynchronize (the kernel)");
    float ms = 0.0f;
    check_cuda(cudaEventElapsedTime(&ms, start, stop), "cudaEventElapsedTime");
    cudaEventDestroy(start);
    cudaEventDestroy(stop);
    return ms;
}

}  // namespace lancer::gpu
