// The launchers of kernels.cu, declared without CUDA types so that the host code (tracer.cpp) stays plain
// C++. Pointers in LaunchScene, LaunchRays and the arguments are device pointers.
#pragma once

#include <cstdint>

#include "cuda/cwbvh_layout.hpp"
#include "cuda/gpu_layout.hpp"
#include "lancer/cuda.hpp"

namespace lancer::gpu {

struct LaunchScene {
    BvhView bvh;
    CwbvhView cwbvh;
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

// Where a launch writes, device pointers indexed by slot (a batch's ray index, or a frame's y * width + x):
// the closest hits, with occluded null; or, for an any-hit query of a batch, one occlusion byte per ray (1:
// something lies in [tnear, tfar]), with hits null. With `steps` not null a closest-hit launch also writes
// each ray's step count there (CountSteps).
struct LaunchAnswers {
    Hit* hits = nullptr;
    std::uint8_t* occluded = nullptr;
    std::uint32_t* steps = nullptr;
};

// Runs `kernel` over the rays and returns the kernel's milliseconds (CUDA events). `next_ray` is one device
// word, the persistent threads' counter. Throws CudaError when a CUDA call fails.
[[nodiscard]] float launch_trace(CudaKernel kernel, const LaunchScene& scene, const LaunchRays& rays,
                                 const LaunchAnswers& answers, std::uint32_t* next_ray);

}  // namespace lancer::gpu
