// lancer bench --device cuda: the GPU kernels on the views of VIEWS.md, validated against the CPU structure
// on the same rays before they are timed. The time is the kernel's alone (CUDA events): on the primary view
// ray generation is in the kernel and the transfers of the hits are not, as in Portalez & Duguet 2016,
// Table 2; the diffuse and shadow views are uploaded once and traced from device memory, the shadow view by
// the any-hit kernels.
#include <fmt/core.h>

#include <algorithm>
#include <cstring>

#include "bench_trace.hpp"
#include "cuda_device.hpp"
#include "lancer/agreement.hpp"
#include "lancer/camera.hpp"

namespace lancer::cli {

namespace {

std::vector<std::string> cuda_structures(const std::vector<std::string>& requested) {
    if (requested.size() == 1 && requested[0] == "all") return {"plucker", "bvh", "bvh8"};
    for (const std::string& name : requested)
        if (name != "plucker" && name != "bvh" && name != "bvh8")
            throw InputError(
                fmt::format("--device cuda benches --accel plucker, bvh and bvh8, not '{}'", name));
    return requested;
}

std::vector<CudaKernel> kernels_of(const DeviceChoice& device, const std::string& accel) {
    if (!device.kernel.empty()) return {device.kernel_for(accel)};
    if (accel == "plucker") return {CudaKernel::Plucker};
    if (accel == "bvh8") return {CudaKernel::CompressedWide};
    return {CudaKernel::WhileWhile, CudaKernel::SpeculativeWhileWhile, CudaKernel::Persistent};
}

// One kernel's row: the warm-up trace validated against the CPU's answers, then `frames` timed traces.
struct CudaViewRun {
    Agreement agreement;
    // Answers equal to the CPU's byte for byte (the whole Hit, or the occlusion byte): the kernels are built
    // to give every one (docs/cuda.md, "Design").
    std::size_t bit_identical = 0;
    std::vector<double> mrays;  // sorted
};

CudaViewRun run_view(CudaTracer& tracer, const ViewRays& view, std::span<const Hit> expected,
                     const Camera& camera, int frames) {
    const bool any_hit = view.view == BenchView::Shadow;
    // The primary view's rays are made in the kernel (Table 2's timing); the others are uploaded once and
    // traced from device memory (VIEWS.md).
    const auto trace = [&] {
        return view.view == BenchView::Primary ? tracer.trace_frame(camera) : tracer.trace_uploaded(any_hit);
    };
    if (view.view != BenchView::Primary) tracer.upload_rays(view.rays);
    CudaViewRun run;
    const CudaTrace first = trace();
    run.agreement = any_hit ? compare_occlusion(view.rays, expected, first.occluded)
                            : compare_hits(view.rays, expected, first.hits);
    for (std::size_t i = 0; i < view.rays.size(); ++i) {
        const bool same = any_hit ? (first.occluded[i] != 0) == expected[i].hit()
                                  : std::memcmp(&first.hits[i], &expected[i], sizeof(Hit)) == 0;
        run.bit_identical += same ? 1 : 0;
    }
    for (int frame = 0; frame < frames; ++frame) {
        const CudaTrace traced = trace();
        run.mrays.push_back(static_cast<double>(view.rays.size()) / (traced.kernel_ms * 1e3));
    }
    std::sort(run.mrays.begin(), run.mrays.end());
    return run;
}

}  // namespace

void run_cuda_bench(const DeviceChoice& device, std::span<const CudaBenchMesh> meshes,
                    const CudaBenchOptions& options) {
    device.require_available();
    const std::vector<std::string> accels = cuda_structures(options.accels);
    bool header_printed = false;
    bool agreement_failed = false;
    for (const CudaBenchMesh& mesh : meshes) {
        const SceneGeometry geometry(*mesh.scene);
        const Camera camera = canonical_view(geometry.view().bounds(), options.size, options.size);
        const std::vector<ViewRays> views =
            make_views(options.views, geometry.view(), PinholeCamera(camera), options.watertight);
        for (const std::string& name : accels) {
            const AccelChoice choice{name, options.watertight, options.settings};
            const BuiltAccel built = build_timed(choice, geometry.view());
            // The CPU structure's closest hits on each view: the shadow view's occlusion is "has a hit".
            std::vector<std::vector<Hit>> expected;
            for (const ViewRays& view : views) {
                expected.emplace_back(view.rays.size());
                intersect_parallel(*built.accel, view.rays, expected.back(), 0);
            }
            for (const CudaKernel kernel : kernels_of(device, name)) {
                DeviceChoice chosen = device;
                chosen.kernel = cuda_kernel_name(kernel);
                const std::unique_ptr<CudaTracer> tracer = make_cuda_tracer(
                    chosen, choice.build_options().triangle_test, *built.accel, geometry.view());
                if (!header_printed) {
                    fmt::print(
                        "lancer bench --device cuda: {}; {}x{} canonical view, {} frames after 1 warm-up\n",
                        tracer->device_name(), options.size, options.size, options.frames);
                    fmt::print("{:<16} {:<7} {:>9} {:<8} {:<12} {:>10} {:>9} {:>9} {:>9} {:>6}  {}\n", "mesh",
                               "view", "triangles", "accel", "kernel", "build ms", "Mrays/s", "min", "max",
                               "hits", "agreement with the CPU");
                    header_printed = true;
                }
                for (std::size_t v = 0; v < views.size(); ++v) {
                    const CudaViewRun run = run_view(*tracer, views[v], expected[v], camera, options.frames);
                    if (run.bit_identical != views[v].rays.size()) agreement_failed = true;
                    fmt::print(
                        "{:<16} {:<7} {:>9} {:<8} {:<12} {:>10.1f} {:>9.1f} {:>9.1f} {:>9.1f} {:>5.1f}%  "
                        "{}\n",
                        mesh.name, view_name(views[v].view), geometry.triangle_count(), name,
                        cuda_kernel_name(kernel), built.build_ms, run.mrays[run.mrays.size() / 2],
                        run.mrays.front(), run.mrays.back(),
                        100.0 * static_cast<double>(run.agreement.hits) /
                            static_cast<double>(views[v].rays.size()),
                        fmt::format("{}, {} bit-identical", run.agreement.summary(), run.bit_identical));
                    std::fflush(stdout);
                }
            }
        }
    }
    if (agreement_failed)
        throw CheckFailure("bench: a GPU kernel's answers are not the CPU's bit for bit (see above)");
}

}  // namespace lancer::cli
