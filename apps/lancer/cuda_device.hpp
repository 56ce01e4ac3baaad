// `--device cpu|cuda` for bench, render and rays (docs/cuda.md): the option, the early refusal when no CUDA
// device can be used (exit code 2), and the GPU paths themselves, kept out of the commands' files.
#pragma once

#include <span>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench_report.hpp"
#include "common.hpp"
#include "lancer/cuda.hpp"
#include "lancer/render.hpp"

namespace lancer::cli {

struct DeviceChoice {
    std::string device = "cpu";
    std::string kernel;  // empty: the structure's default (default_cuda_kernel)

    void add_options(CLI::App& command);
    [[nodiscard]] bool cuda() const { return device == "cuda"; }
    // With --device cuda: throws InputError "--device cuda: no CUDA device (cudaGetDeviceCount: ...)"
    // when no device can be used. Commands call it before loading anything.
    void require_available() const;
    // The kernel for structure `accel_name`; throws InputError for a structure no kernel traces, or a
    // --cuda-kernel that does not trace it.
    [[nodiscard]] CudaKernel kernel_for(std::string_view accel_name) const;
};

// A tracer for `accel`, built on `geometry` with `triangle_test`; CUDA and input errors become InputError.
[[nodiscard]] std::unique_ptr<CudaTracer> make_cuda_tracer(const DeviceChoice& device,
                                                           TriangleTest triangle_test, const Accel& accel,
                                                           const Geometry& geometry);

// `lancer bench --device cuda`: every kernel of each structure (plucker, bvh, bvh8) on each mesh's views (the
// canonical view, and the diffuse and shadow views made from it), validated against the CPU structure,
// timed by CUDA events (the kernel alone).
struct CudaBenchMesh {
    std::string name;
    const Scene* scene;
};
struct CudaBenchOptions {
    std::vector<std::string> accels;  // "all" expands to plucker, bvh, bvh8
    std::vector<BenchView> views;
    int size = 1024;
    int frames = 5;
    bool watertight = true;
    std::vector<std::string> settings;
};
void run_cuda_bench(const DeviceChoice& device, std::span<const CudaBenchMesh> meshes,
                    const CudaBenchOptions& options);

}  // namespace lancer::cli
