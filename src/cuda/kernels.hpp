// The launchers of kernels.cu, declared without CUDA types so that the host code (tracer.cpp) stays plain
// C++. Pointers in LaunchScene, LaunchRays and the arguments are device pointers.
#pragma once

#include <cstdint>

#include "cuda/gpu_layout.hpp"
#include "lancer/cuda.hpp"

namespace lancer::gpu {

struct LaunchScene {
    BvhView bvh;
    plucker::PluckerView plucker;
    bool watertight = false;
};

// A batch (`rays` not null, `count` rays) or, with rays null, the frame of `camera` (frame_ray_count).
struct LaunchRays {
    const Ray* rays = nullptr;
    std::uint32_t count = 0;
    CameraFrame camera;
};

// Copies Portalez & Duguet's tables to constant memory (once per process is enough; idempotent).
void upload_plucker_tables(const plucker::PluckerTables& tables);

// Runs `kernel` over the rays, hits[slot] for each (a frame's slot: y * width + x), and returns the
// kernel's milliseconds (CUDA events). A frame with `steps` not null also writes each ray's step count
// there (NoSteps / CountSteps). `next_ray` is one device word, the persistent threads' counter.
// Throws CudaError when a CUDA call fails.
[[nodiscard]] float launch_trace(CudaKernel kernel, const LaunchScene& scene, const LaunchRays& rays,
                                 Hit* hits, std::uint32_t* steps, std::uint32_t* next_ray);

}  // namespace lancer::gpu
