// render() of a World: on the CPU the image of render(scene, geometry, structure), on the GPU flat and
// heatmap views of scenes without planes, and a clear refusal of everything else.
#include <gtest/gtest.h>

#include <cstring>
#include <stdexcept>

#include "lancer/camera.hpp"
#include "lancer/cuda.hpp"
#include "lancer/generate.hpp"
#include "lancer/render.hpp"
#include "lancer/world.hpp"

namespace lancer {
namespace {

Scene test_scene() {
    Scene scene;
    scene.meshes.push_back(make_icosphere(2, {-1.5f, 0.0f, 0.0f}, 1.0f));
    scene.spheres.push_back({{2.0f, 1.0f, 0.5f}, 0.5f, 0});
    scene.materials.resize(1);
    return scene;
}

TEST(RenderWorld, RendersOnTheCpuAsTheSceneGeometryAndStructureDo) {
    const World world(test_scene(), "bvh", {});
    const Camera camera = canonical_view(world.scene().bounds(), 48, 32);
    RenderOptions options;
    options.mode = ShadingMode::Flat;
    const Image expected = render(world.scene(), world.geometry(), world.accel(), camera, options);
    const Image image = render(world, camera, options);
    ASSERT_EQ(image.pixels.size(), expected.pixels.size());
    EXPECT_EQ(std::memcmp(image.pixels.data(), expected.pixels.data(), image.pixels.size() * sizeof(Vec3f)),
              0);
}

TEST(RenderWorld, TheGpuRendersFlatAndHeatmapOfSceneWithoutPlanes) {
    const World world(test_scene(), "bvh", {});
    const Camera camera = canonical_view(world.scene().bounds(), 16, 16);
    RenderOptions options;
    options.device = RenderDevice::Cuda;
    options.mode = ShadingMode::Whitted;
    EXPECT_THROW(static_cast<void>(render(world, camera, options)), std::invalid_argument);
    Scene with_plane = test_scene();
    with_plane.planes.push_back({{0.0f, 1.0f, 0.0f}, -3.0f, 0, false});
    options.mode = ShadingMode::Flat;
    EXPECT_THROW(static_cast<void>(render(World(with_plane, "bvh", {}), camera, options)),
                 std::invalid_argument);
    // The CPU-only entry refuses the GPU instead of rendering on the CPU unasked.
    EXPECT_THROW(static_cast<void>(render(world.scene(), world.geometry(), world.accel(), camera, options)),
                 std::invalid_argument);
    if (cuda_available()) {
        const Image image = render(world, camera, options);
        EXPECT_EQ(image.width, 16);
    } else {
        EXPECT_THROW(static_cast<void>(render(world, camera, options)), CudaError);
    }
}

}  // namespace
}  // namespace lancer
