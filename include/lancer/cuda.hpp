// The GPU path (docs/cuda.md): a built `plucker` or `bvh` structure uploaded once to an NVIDIA GPU
// and traced there, a frame of the canonical camera or a batch of rays at a time. Built with LANCER_CUDA;
// without it every call but cuda_available throws CudaError ("built without CUDA").
#pragma once

#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer {

enum class CudaKernel {
    Plucker,     // Portalez & Duguet 2016, 5.2: the Plücker walk, a thread per ray (a `plucker` structure)
    WhileWhile,  // Aila & Laine 2009, while-while (a `bvh` structure)
    SpeculativeWhileWhile,  // Aila & Laine 2009, speculative while-while
    Persistent,             // speculative while-while in persistent threads fetching warp-sized batches
    CompressedWide,  // Ylitie, Karras & Laine 2017: the compressed 8-wide BVH made from a `bvh8` structure
};

// "plucker", "while-while", "speculative", "persistent", "cwbvh".
[[nodiscard]] std::string_view cuda_kernel_name(CudaKernel kernel);
// The kernel of a name above; throws std::invalid_argument naming the accepted ones.
[[nodiscard]] CudaKernel parse_cuda_kernel(std::string_view name);
// The structure a kernel traces: "plucker", "bvh" or "bvh8".
[[nodiscard]] std::string_view cuda_kernel_structure(CudaKernel kernel);
// The kernel that traces structure `accel_name` by default: Plucker for plucker, Persistent for bvh,
// CompressedWide for bvh8; throws std::invalid_argument for a structure no kernel traces.
[[nodiscard]] CudaKernel default_cuda_kernel(std::string_view accel_name);

class CudaError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Whether a CUDA device can be used; otherwise `why` (if given) says why: "built without CUDA", or the
// error of cudaGetDeviceCount, or "no CUDA device".
[[nodiscard]] bool cuda_available(std::string* why = nullptr);

struct CudaTrace {
    std::vector<Hit> hits;  // closest hits, one per ray; a frame's row by row
    // Occlusion queries: one byte per ray, 1 when something lies in [tnear, tfar] (Accel::occluded's
    // answer); `hits` is then empty.
    std::vector<std::uint8_t> occluded;
    double kernel_ms = 0.0;  // the kernel alone (CUDA events), transfers excluded
    // trace_frame(camera, true) only: per ray, the inner nodes and leaves (bvh) or the leaves (plucker)
    // visited, TraversalCounters::nodes_visited's meaning, or the nodes and triangle groups (cwbvh): the
    // heatmap.
    std::vector<std::uint32_t> steps;
};

class CudaTracer {
  public:
    // `accel` is a built `plucker` or `plucker_packet` (kernel Plucker), a `bvh8` or `bvh8_packet`
    // (CompressedWide, converted here), or a `bvh` or `bvh_packet` (the others) on `geometry`, with `test`
    // its triangle test: the packet structures lend their single-ray structure's arrays. Uploads the arrays
    // once. Throws CudaError (no device, a CUDA call failed) or std::invalid_argument (a structure or scene
    // the kernels do not trace: another structure, spheres).
    CudaTracer(const Accel& accel, const Geometry& geometry, TriangleTest test, CudaKernel kernel);
    ~CudaTracer();
    CudaTracer(const CudaTracer&) = delete;
    CudaTracer& operator=(const CudaTracer&) = delete;

    // The primary rays of `camera` (PinholeCamera's, through pixel centres), width x height; with
    // count_steps, each ray's traversal steps too (a slower kernel: for pictures, not for timing).
    [[nodiscard]] CudaTrace trace_frame(const Camera& camera, bool count_steps = false);
    // Closest hits of a batch of rays. Rays are conditioned first, as Accel::intersect does.
    [[nodiscard]] CudaTrace trace(std::span<const Ray> rays);
    // Occlusion of a batch (CudaTrace::occluded), the kernels stopping at a ray's first hit.
    [[nodiscard]] CudaTrace occluded(std::span<const Ray> rays);

    // A batch kept on the device, so that it is traced many times from device memory, as VIEWS.md times
    // the secondary views: upload_rays conditions and copies `rays` once; trace_uploaded answers them
    // (closest hits, or with any_hit their occlusion), timing the kernel alone. Throws std::logic_error
    // before any upload.
    void upload_rays(std::span<const Ray> rays);
    [[nodiscard]] CudaTrace trace_uploaded(bool any_hit);

    [[nodiscard]] std::string device_name() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace lancer
