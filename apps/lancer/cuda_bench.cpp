// lancer bench --device cuda: the GPU kernels on the canonical view (VIEWS.md), validated against the CPU
// structure on the same rays before they are timed. The time is the kernel's alone (CUDA events): ray
// generation is in the kernel, the transfers of the hits are not, as in Portalez & Duguet, "Lancer de rayons
// dans un octree" (2016), Table 2.
#include <fmt/core.h>

#include <algorithm>

#include "cuda_device.hpp"
#include "lancer/agreement.hpp"
#include "lancer/camera.hpp"

namespace lancer::cli {

namespace {

std::vector<std::string> cuda_structures(const std::vector<std::string>& requested) {
    if (requested.size() == 1 && requested[0] == "all") return {"plucker", "bvh"};
    for (const std::string& name : requested)
        if (name != "plucker" && name != "bvh")
            throw InputError(fmt::format("--device cuda benches --accel plucker and bvh, not '{}'", name));
    return requested;
}

std::vector<CudaKernel> kernels_of(const DeviceChoice& device, const std::string& accel) {
    if (!device.kernel.empty()) return {device.kernel_for(accel)};
    if (accel == "plucker") return {CudaKernel::Plucker};
    return {CudaKernel::WhileWhile, CudaKernel::SpeculativeWhileWhile, CudaKernel::Persistent};
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
        const PinholeCamera pinhole(camera);
        std::vector<Ray> rays;
        rays.reserve(static_cast<std::size_t>(options.size) * static_cast<std::size_t>(options.size));
        for (int j = 0; j < options.size; ++j)
            for (int i = 0; i < options.size; ++i)
                rays.push_back(pinhole.generate(static_cast<float>(i) + 0.5f, static_cast<float>(j) + 0.5f));
        for (const std::string& name : accels) {
            const AccelChoice choice{name, options.watertight, options.settings};
            const BuiltAccel built = build_timed(choice, geometry.view());
            std::vector<Hit> expected(rays.size());
            intersect_parallel(*built.accel, rays, expected, 0);
            for (const CudaKernel kernel : kernels_of(device, name)) {
                DeviceChoice chosen = device;
                chosen.kernel = cuda_kernel_name(kernel);
                const std::unique_ptr<CudaTracer> tracer = make_cuda_tracer(
                    chosen, choice.build_options().triangle_test, *built.accel, geometry.view());
                if (!header_printed) {
                    fmt::print(
                        "lancer bench --device cuda: {}; {}x{} canonical view, {} frames after 1 warm-up\n",
                        tracer->device_name(), options.size, options.size, options.frames);
                    fmt::print("{:<16} {:>9} {:<8} {:<12} {:>10} {:>9} {:>9} {:>9} {:>6}  {}\n", "mesh",
                               "triangles", "accel", "kernel", "build ms", "Mrays/s", "min", "max", "hits",
                               "agreement with the CPU");
                    header_printed = true;
                }
                // The warm-up frame is the validated one.
                const CudaTrace first = tracer->trace_frame(camera);
                const Agreement agreement = compare_hits(rays, expected, first.hits);
                if (agreement.mismatches > 0) agreement_failed = true;
                std::vector<double> mrays;
                for (int frame = 0; frame < options.frames; ++frame) {
                    const CudaTrace traced = tracer->trace_frame(camera);
                    mrays.push_back(static_cast<double>(rays.size()) / (traced.kernel_ms * 1e3));
                }
                std::sort(mrays.begin(), mrays.end());
                fmt::print("{:<16} {:>9} {:<8} {:<12} {:>10.1f} {:>9.1f} {:>9.1f} {:>9.1f} {:>5.1f}%  {}\n",
                           mesh.name, geometry.triangle_count(), name, cuda_kernel_name(kernel),
                           built.build_ms, mrays[mrays.size() / 2], mrays.front(), mrays.back(),
                           100.0 * static_cast<double>(agreement.hits) / static_cast<double>(rays.size()),
                           agreement.summary());
                std::fflush(stdout);
            }
        }
    }
    if (agreement_failed) throw CheckFailure("bench: a GPU kernel disagrees with the CPU (see above)");
}

}  // namespace lancer::cli
