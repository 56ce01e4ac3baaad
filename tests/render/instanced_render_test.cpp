// render() of an InstancedWorld (lancer/world.hpp): in every mode the image of the same scene flattened (each
// instance's mesh moved into a mesh of its own) up to the transformed rays' rounding; a World refuses the
// instances it would leave out.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "lancer/camera.hpp"
#include "lancer/generate.hpp"
#include "lancer/render.hpp"
#include "lancer/world.hpp"

namespace lancer {
namespace {

// Spheres with vertex normals and a tetrahedron placed five times (a mirror and a non-uniform scale among
// them), beside a mesh, a sphere and a checkered plane of the scene's own; a reflective material and a light,
// so that Whitted mode traces shadow and reflected rays through the instances.
Scene instanced_scene() {
    Scene scene;
    scene.materials.resize(3);
    scene.materials[1].color = {0.9f, 0.3f, 0.2f};
    scene.materials[2].ks = 0.4f;
    scene.lights.push_back({{4.0f, 6.0f, 5.0f}, Vec3f(1.0f)});
    TriangleMesh ball = make_icosphere(2, Vec3f(0.0f), 0.6f);
    ball.material = 2;
    TriangleMesh tetrahedron;
    tetrahedron.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    tetrahedron.indices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    tetrahedron.material = 1;
    scene.instanced_meshes = {ball, tetrahedron};
    const Transform mirror = Transform::scaling({-1.0f, 1.0f, 1.0f});
    scene.instances = {
        {0, Transform::translation({-2.0f, 0.0f, 0.0f})},
        {0, Transform::translation({0.5f, 0.2f, -1.0f}) * Transform::scaling({1.0f, 0.5f, 1.5f})},
        {1, Transform::translation({1.8f, -0.5f, 0.5f}) * Transform::rotation({1.0f, 1.0f, 0.0f}, 0.7f)},
        {1, Transform::translation({-0.5f, -0.8f, 1.2f}) * mirror},
        {0, Transform::translation({2.5f, 1.2f, -0.5f}) * Transform::rotation({0.0f, 0.0f, 1.0f}, 1.1f)},
    };
    scene.meshes.push_back(make_icosphere(1, {0.0f, 1.5f, 0.0f}, 0.5f));
    scene.spheres.push_back({{-1.0f, 1.2f, 1.0f}, 0.4f, 1});
    scene.planes.push_back({{0.0f, 1.0f, 0.0f}, -1.0f, 0, true});
    return scene;
}

// The scene with each instance's mesh moved into a mesh of its own, vertex normals as the renderer moves
// them.
Scene flattened(Scene scene) {
    for (const MeshInstance& instance : scene.instances) {
        TriangleMesh mesh = scene.instanced_meshes[instance.mesh];
        for (Vec3f& position : mesh.positions)
            position = instance.object_to_world.point(position);
        for (Vec3f& normal : mesh.normals)
            normal = instance.object_to_world.normal(normal);
        scene.meshes.push_back(std::move(mesh));
    }
    scene.instances.clear();
    scene.instanced_meshes.clear();
    return scene;
}

// The share of pixels whose colours differ by more than `tolerance` in a channel.
double differing_share(const Image& a, const Image& b, float tolerance) {
    std::size_t differing = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) {
        const Vec3f d = abs(a.pixels[i] - b.pixels[i]);
        differing += std::max({d.x, d.y, d.z}) > tolerance ? 1 : 0;
    }
    return static_cast<double>(differing) / static_cast<double>(a.pixels.size());
}

TEST(InstancedRender, EveryModeRendersAsTheSceneFlattened) {
    const InstancedWorld instanced(instanced_scene(), "bvh8", {});
    const World flat(flattened(instanced_scene()), "bvh8", {});
    EXPECT_EQ(instanced.scene().instanced_triangle_count(), flat.scene().triangle_count());
    const Camera camera = canonical_view(instanced.scene().bounds(), 96, 80);
    for (const ShadingMode mode : {ShadingMode::Whitted, ShadingMode::Flat, ShadingMode::Normal,
                                   ShadingMode::Depth, ShadingMode::Heatmap}) {
        RenderOptions options;
        options.mode = mode;
        options.samples_per_pixel = 1;
        RenderStats instanced_stats, flat_stats;
        const Image image = render(instanced, camera, options, &instanced_stats);
        const Image expected = render(flat, camera, options, &flat_stats);
        ASSERT_EQ(image.pixels.size(), expected.pixels.size());
        const auto background = static_cast<std::size_t>(
            std::count(image.pixels.begin(), image.pixels.end(), instanced.scene().background));
        EXPECT_LT(background, image.pixels.size() / 2) << static_cast<int>(mode);
        EXPECT_EQ(instanced_stats.primary_rays, flat_stats.primary_rays);
        if (mode == ShadingMode::Heatmap) {
            // Another structure walks another count of nodes: the counts are there, the picture is not the
            // same.
            EXPECT_EQ(instanced_stats.counters.rays, image.pixels.size());
            EXPECT_GT(instanced_stats.counters.nodes_visited, instanced_stats.counters.rays);
            continue;
        }
        // A few silhouette pixels may go either way by a rounding of the transformed rays.
        EXPECT_LT(differing_share(image, expected, 0.02f), 0.002) << static_cast<int>(mode);
        if (mode == ShadingMode::Whitted) {
            EXPECT_GT(instanced_stats.shadow_rays, 0u);
            EXPECT_GT(instanced_stats.reflection_rays, 0u);
            const double rays = static_cast<double>(flat_stats.total_rays());
            EXPECT_NEAR(static_cast<double>(instanced_stats.total_rays()), rays, 0.01 * rays);
        }
    }
}

TEST(InstancedRender, AWorldRefusesInstancesAndTheGpuRefusesAnInstancedWorld) {
    try {
        const World world(instanced_scene(), "bvh8", {});
        ADD_FAILURE() << "a World took a scene with instances";
    } catch (const std::invalid_argument& error) {
        EXPECT_NE(std::string(error.what()).find("5 instances"), std::string::npos) << error.what();
    }
    const InstancedWorld instanced(instanced_scene(), "bvh8", {});
    RenderOptions options;
    options.device = RenderDevice::Cuda;
    options.mode = ShadingMode::Flat;
    EXPECT_THROW(
        static_cast<void>(render(instanced, canonical_view(instanced.scene().bounds(), 8, 8), options)),
        std::invalid_argument);
    Scene singular = instanced_scene();
    singular.instances[3].object_to_world = Transform::scaling({1.0f, 0.0f, 1.0f});
    try {
        const InstancedWorld refused(std::move(singular), "bvh8", {});
        ADD_FAILURE() << "a singular instance was taken";
    } catch (const std::invalid_argument& error) {
        EXPECT_NE(std::string(error.what()).find("instance 3"), std::string::npos) << error.what();
    }
}

}  // namespace
}  // namespace lancer
