// render() of a World on the GPU: the primary rays traced in one launch by CudaTracer, shaded here.
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

#include "lancer/camera.hpp"
#include "lancer/render.hpp"
#include "render/heatmap.hpp"
#include "render/scene_intersector.hpp"

namespace lancer {

namespace {

Image render_on_cuda(const World& world, const Camera& camera, const RenderOptions& options,
                     RenderStats& stats) {
    const Scene& scene = world.scene();
    if (camera.width <= 0 || camera.height <= 0) {
        throw std::invalid_argument("render: image size " + std::to_string(camera.width) + "x" +
                                    std::to_string(camera.height) + " is not positive");
    }
    if (options.mode != ShadingMode::Flat && options.mode != ShadingMode::Heatmap)
        throw std::invalid_argument("render on the GPU: the mode must be flat or heatmap");
    if (!scene.planes.empty())
        throw std::invalid_argument(
            "render on the GPU: the scene has infinite planes; the GPU kernels trace triangles only");
    const Accel& accel = world.accel();
    const CudaKernel kernel = options.cuda_kernel.value_or(default_cuda_kernel(accel.name()));
    CudaTracer tracer(accel, world.geometry().view(), world.options().triangle_test, kernel);
    const bool heatmap = options.mode == ShadingMode::Heatmap;
    const CudaTrace traced = tracer.trace_frame(camera, heatmap);

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
    const SceneIntersector intersector(scene, world.geometry(), accel);
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
            const SurfacePoint surface = intersector.surface(ray, {hit.t, hit.prim, hit.u, hit.v, -1, -1});
            image.at(x, y) =
                surface.color * std::fabs(dot(surface.geometric_normal, normalize(ray.direction)));
        }
    }
    return image;
}

}  // namespace

Image render(const World& world, const Camera& camera, const RenderOptions& options, RenderStats* stats) {
    if (options.device == RenderDevice::Cpu)
        return render(world.scene(), world.geometry(), world.accel(), camera, options, stats);
    // The CPU-only options (threads, tiles, progress, Whitted's) do not apply to the GPU's single launch.
    RenderStats local;
    return render_on_cuda(world, camera, options, stats != nullptr ? *stats : local);
}

}  // namespace lancer
