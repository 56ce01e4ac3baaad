#include "cuda_device.hpp"

#include <cmath>
#include <stdexcept>

#include "lancer/camera.hpp"
#include "render/heatmap.hpp"
#include "render/scene_intersector.hpp"

namespace lancer::cli {

void DeviceChoice::add_options(CLI::App& command) {
    command.add_option("--device", device, "Where to trace: cpu, or cuda (an NVIDIA GPU; docs/cuda.md)")
        ->transform(one_of(std::vector<std::string>{"cpu", "cuda"}))
        ->capture_default_str();
    std::vector<std::string> kernels;
    for (const CudaKernel each : {CudaKernel::Plucker, CudaKernel::WhileWhile,
                                  CudaKernel::SpeculativeWhileWhile, CudaKernel::Persistent})
        kernels.emplace_back(cuda_kernel_name(each));
    command
        .add_option("--cuda-kernel", kernel,
                    "With --device cuda: plucker, while-while, speculative or persistent (default: plucker "
                    "for --accel plucker, persistent for bvh)")
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
        if ((chosen == CudaKernel::Plucker) != (fallback == CudaKernel::Plucker)) {
            throw std::invalid_argument("--cuda-kernel " + kernel + " does not trace --accel " +
                                        std::string(accel_name));
        }
        return chosen;
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    }
}

std::unique_ptr<CudaTracer> make_cuda_tracer(const DeviceChoice& device, const AccelChoice& choice,
                                             const Accel& accel, const Geometry& geometry) {
    const CudaKernel kernel = device.kernel_for(accel.name());
    try {
        return std::make_unique<CudaTracer>(accel, geometry, choice.build_options().triangle_test, kernel);
    } catch (const CudaError& error) {
        throw InputError(std::string("--device cuda: ") + error.what());
    } catch (const std::invalid_argument& error) {
        throw InputError(std::string("--device cuda: ") + error.what());
    }
}

Image render_on_cuda(const DeviceChoice& device, const AccelChoice& choice, const Scene& scene,
                     const SceneGeometry& geometry, const Accel& accel, const Camera& camera,
                     ShadingMode mode, RenderStats& stats) {
    if (!scene.planes.empty())
        throw InputError(
            "--device cuda: the scene has infinite planes; the GPU kernels trace triangles only");
    const std::unique_ptr<CudaTracer> tracer = make_cuda_tracer(device, choice, accel, geometry.view());
    const bool heatmap = mode == ShadingMode::Heatmap;
    const CudaTrace traced = tracer->trace_frame(camera, heatmap);

    Image image(camera.width, camera.height);
    stats.trace_ms = traced.kernel_ms;
    stats.primary_rays = traced.hits.size();
    if (heatmap) {
        stats.counters.rays = traced.steps.size();
        for (const std::uint32_t steps : traced.steps)
            stats.counters.nodes_visited += steps;
        heat_to_image(traced.steps, image);
        return image;
    }
    // Flat shading (render.cpp's Figure 5 look): the material colour times |cos| with the view.
    const SceneIntersector intersector(scene, geometry, accel);
    const PinholeCamera pinhole(camera);
    for (int y = 0; y < camera.height; ++y) {
        for (int x = 0; x < camera.width; ++x) {
            const Hit& hit =
                traced.hits[static_cast<std::size_t>(y) * static_cast<std::size_t>(camera.width) +
                            static_cast<std::size_t>(x)];
            if (!hit.hit()) {
                image.at(x, y) = scene.background;
                continue;
            }
            const Ray ray = pinhole.generate(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
            const SurfacePoint surface = intersector.surface(ray, hit);
            image.at(x, y) =
                surface.color * std::fabs(dot(surface.geometric_normal, normalize(ray.direction)));
        }
    }
    return image;
}

}  // namespace lancer::cli
