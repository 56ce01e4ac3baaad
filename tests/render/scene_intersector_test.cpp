// The structure and the planes together: who wins, plane ids, and what surface() recovers per primitive.
#include "render/scene_intersector.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "accel/brute.hpp"
#include "print_vec.hpp"

namespace lancer {
namespace {

// A scene with its geometry and a built brute-force structure, kept alive together.
struct Traced {
    Scene scene;
    SceneGeometry geometry;
    BruteAccel accel;
    SceneIntersector intersector;

    explicit Traced(Scene s)
        : scene(std::move(s)), geometry(scene), accel(built(geometry)), intersector(scene, geometry, accel) {}

    static BruteAccel built(const SceneGeometry& geometry) {
        BruteAccel accel;
        accel.build(geometry.view(), {});
        return accel;
    }

    InstanceHit trace(const Ray& ray) const {
        InstanceHit hit;
        intersector.intersect({&ray, 1}, {&hit, 1});
        return hit;
    }
};

// A large triangle in the plane z = depth, facing +z.
TriangleMesh wall(float depth, std::uint32_t material = 0) {
    TriangleMesh mesh;
    mesh.positions = {{-10.0f, -10.0f, depth}, {10.0f, -10.0f, depth}, {0.0f, 10.0f, depth}};
    mesh.indices = {0, 1, 2};
    mesh.material = material;
    return mesh;
}

Plane plane_z(float offset) {
    return {{0.0f, 0.0f, 1.0f}, offset, 0, false};
}

Scene with_materials(Scene scene, std::size_t count) {
    scene.materials.resize(count);
    for (std::size_t i = 0; i < count; ++i)
        scene.materials[i].color = Vec3f(0.1f * static_cast<float>(i + 1));
    return scene;
}

Ray ray_down_z(Vec3f origin = {0.0f, 0.0f, 0.0f}) {
    return {origin, {0.0f, 0.0f, -1.0f}};
}

TEST(SceneIntersector, PlaneInFrontOfTheStructureWins) {
    Scene scene;
    scene.meshes.push_back(wall(-3.0f));
    scene.planes.push_back(plane_z(-1.0f));
    const Traced traced(with_materials(scene, 1));
    const InstanceHit hit = traced.trace(ray_down_z());
    EXPECT_EQ(hit.prim, 1);  // geometry size 1 + plane 0
    EXPECT_EQ(hit.t, 1.0f);
}

TEST(SceneIntersector, StructureInFrontOfThePlaneWins) {
    Scene scene;
    scene.meshes.push_back(wall(-0.5f));
    scene.planes.push_back(plane_z(-1.0f));
    const Traced traced(with_materials(scene, 1));
    const InstanceHit hit = traced.trace(ray_down_z());
    EXPECT_EQ(hit.prim, 0);
    EXPECT_EQ(hit.t, 0.5f);
}

TEST(SceneIntersector, StructureWinsAnExactTie) {
    Scene scene;
    scene.meshes.push_back(wall(-1.0f));
    scene.planes.push_back(plane_z(-1.0f));
    const Traced traced(with_materials(scene, 1));
    const InstanceHit hit = traced.trace(ray_down_z());
    ASSERT_EQ(hit.t, 1.0f);
    EXPECT_EQ(hit.prim, 0);
}

TEST(SceneIntersector, PlaneIdsFollowTrianglesAndSpheres) {
    Scene scene;
    scene.meshes.push_back(wall(-50.0f));
    scene.spheres.push_back({{100.0f, 0.0f, 0.0f}, 1.0f, 0});
    scene.planes.push_back(plane_z(-2.0f));
    scene.planes.push_back(plane_z(-1.5f));
    scene.planes.push_back(plane_z(-3.0f));
    const Traced traced(with_materials(scene, 1));
    const InstanceHit hit = traced.trace(ray_down_z());
    EXPECT_EQ(hit.prim, 2 + 1);  // 1 triangle + 1 sphere, then the nearest plane, index 1
    EXPECT_EQ(hit.t, 1.5f);
}

TEST(SceneIntersector, PlanesRespectTheRayInterval) {
    Scene scene;
    scene.planes.push_back(plane_z(-1.0f));
    const Traced traced(with_materials(scene, 1));
    Ray short_ray = ray_down_z();
    short_ray.tfar = 0.5f;
    EXPECT_FALSE(traced.trace(short_ray).hit());
    Ray late_ray = ray_down_z();
    late_ray.tnear = 2.0f;
    EXPECT_FALSE(traced.trace(late_ray).hit());
    Ray behind = ray_down_z({0.0f, 0.0f, -2.0f});
    EXPECT_FALSE(traced.trace(behind).hit());
}

TEST(SceneIntersector, InvalidRaysMissThePlanes) {
    Scene scene;
    scene.planes.push_back(plane_z(-1.0f));
    const Traced traced(with_materials(scene, 1));
    Ray nan_ray = ray_down_z();
    nan_ray.direction.x = std::numeric_limits<float>::quiet_NaN();
    EXPECT_FALSE(traced.trace(nan_ray).hit());
    const Ray zero_direction{{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}};
    EXPECT_FALSE(traced.trace(zero_direction).hit());
    // The plane formula alone would answer t = -1 / -inf = 0, a hit at the origin.
    const Ray infinite_direction{{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -std::numeric_limits<float>::infinity()}};
    EXPECT_FALSE(traced.trace(infinite_direction).hit());
}

TEST(SceneIntersector, BatchAnswersEveryRay) {
    Scene scene;
    scene.meshes.push_back(wall(-3.0f));
    scene.planes.push_back(plane_z(-1.0f));
    const Traced traced(with_materials(scene, 1));
    const std::vector<Ray> rays = {ray_down_z(), ray_down_z({0.0f, 0.0f, -2.0f}), {{}, {0.0f, 0.0f, 1.0f}}};
    std::vector<InstanceHit> hits(rays.size());
    traced.intersector.intersect(rays, hits);
    EXPECT_EQ(hits[0].prim, 1);
    EXPECT_EQ(hits[1].prim, 0);
    EXPECT_FALSE(hits[2].hit());
}

TEST(SceneIntersector, TriangleSurfaceFindsItsMeshAndMaterial) {
    Scene scene;
    scene.meshes.push_back(wall(-9.0f, 0));
    TriangleMesh second;
    second.positions = {
        {-10.0f, -10.0f, -2.0f}, {10.0f, -10.0f, -2.0f}, {0.0f, 10.0f, -2.0f}, {0.0f, 10.0f, -1.0f}};
    second.indices = {0, 1, 2, 0, 1, 3};  // the second triangle tilts towards +z, in front of the first
    second.material_ids = {2, 1};
    scene.meshes.push_back(second);
    const Traced traced(with_materials(scene, 3));
    const Ray ray = ray_down_z();
    const InstanceHit hit = traced.trace(ray);
    ASSERT_EQ(hit.prim, 2);  // the second triangle of the second mesh
    const SurfacePoint surface = traced.intersector.surface(ray, hit);
    EXPECT_EQ(surface.material, 1u);
    EXPECT_EQ(surface.color, traced.scene.materials[1].color);
    const Vec3f expected_normal = normalize(Vec3f(0.0f, -1.0f, 20.0f));  // (v1 - v0) x (v3 - v0) / 20
    EXPECT_NEAR(surface.geometric_normal.x, expected_normal.x, 1e-6f);
    EXPECT_NEAR(surface.geometric_normal.y, expected_normal.y, 1e-6f);
    EXPECT_NEAR(surface.geometric_normal.z, expected_normal.z, 1e-6f);
    EXPECT_EQ(surface.shading_normal, surface.geometric_normal);
    EXPECT_NEAR(surface.position.x, 0.0f, 1e-5f);
    EXPECT_NEAR(surface.position.y, 0.0f, 1e-5f);
    EXPECT_NEAR(surface.position.z, -1.5f, 1e-5f);
}

TEST(SceneIntersector, CancellingVertexNormalsFallBackToTheFacet) {
    Scene scene;
    TriangleMesh mesh = wall(-1.0f);
    mesh.normals = {{0.0f, 0.0f, 1.0f}, {0.0f, 0.0f, -1.0f}, {0.0f, 0.0f, 1.0f}};
    scene.meshes.push_back(mesh);
    const Traced traced(with_materials(scene, 1));
    // The point of barycentric weights (1/4, 1/2, 1/4), where 1/4 n0 + 1/2 n1 + 1/4 n2 = 0.
    const Ray ray{{2.5f, -5.0f, 0.0f}, {0.0f, 0.0f, -1.0f}};
    const InstanceHit hit = traced.trace(ray);
    ASSERT_EQ(hit.prim, 0);
    ASSERT_EQ(hit.u, 0.5f);
    ASSERT_EQ(hit.v, 0.25f);
    EXPECT_EQ(traced.intersector.surface(ray, hit).shading_normal, Vec3f(0.0f, 0.0f, 1.0f));
}

TEST(SceneIntersector, SphereSurfaceHasTheRadialNormal) {
    Scene scene;
    scene.spheres.push_back({{0.0f, 0.0f, -5.0f}, 2.0f, 0});
    const Traced traced(with_materials(scene, 1));
    const Ray ray = ray_down_z();
    const InstanceHit hit = traced.trace(ray);
    ASSERT_EQ(hit.prim, 0);
    const SurfacePoint surface = traced.intersector.surface(ray, hit);
    EXPECT_EQ(surface.position, Vec3f(0.0f, 0.0f, -3.0f));
    EXPECT_EQ(surface.geometric_normal, Vec3f(0.0f, 0.0f, 1.0f));
    EXPECT_EQ(surface.shading_normal, Vec3f(0.0f, 0.0f, 1.0f));
}

TEST(SceneIntersector, CheckeredPlaneAlternatesOnTheUnitGrid) {
    Scene scene;
    scene.planes.push_back({{0.0f, 1.0f, 0.0f}, 0.0f, 0, true});
    Traced traced(with_materials(scene, 1));
    const Vec3f color = traced.scene.materials[0].color;
    struct Case {
        float x, z;
        bool full;
    };
    // Cells (floor x, floor z): (0, 0) even, (1, 0) odd, (-1, 0) odd, (-1, -1) even, (3, -2) odd.
    for (const Case& c : {Case{0.5f, 0.5f, true}, Case{1.5f, 0.5f, false}, Case{-0.5f, 0.5f, false},
                          Case{-0.5f, -0.5f, true}, Case{3.25f, -1.75f, false}}) {
        SCOPED_TRACE(testing::Message() << c.x << ", " << c.z);
        const Ray ray{{c.x, 10.0f, c.z}, {0.0f, -1.0f, 0.0f}};
        const InstanceHit hit = traced.trace(ray);
        ASSERT_TRUE(hit.hit());
        const SurfacePoint surface = traced.intersector.surface(ray, hit);
        EXPECT_EQ(surface.color, c.full ? color : 0.25f * color);
        EXPECT_EQ(surface.geometric_normal, Vec3f(0.0f, 1.0f, 0.0f));
    }
}

TEST(SceneIntersector, RejectsAMaterialTheSceneLacks) {
    Scene scene;
    scene.spheres.push_back({{0.0f, 0.0f, -5.0f}, 1.0f, 3});
    scene.materials.resize(1);
    const SceneGeometry geometry(scene);
    BruteAccel accel;
    accel.build(geometry.view(), {});
    EXPECT_THROW(SceneIntersector(scene, geometry, accel), std::invalid_argument);
}

TEST(SceneIntersector, RejectsNormalsThatDoNotMatchThePositions) {
    Scene scene;
    TriangleMesh mesh = wall(-1.0f);
    mesh.normals = {{0.0f, 0.0f, 1.0f}};
    scene.meshes.push_back(mesh);
    scene.materials.resize(1);
    const SceneGeometry geometry(scene);
    BruteAccel accel;
    accel.build(geometry.view(), {});
    EXPECT_THROW(SceneIntersector(scene, geometry, accel), std::invalid_argument);
}

TEST(SceneIntersector, RejectsGeometryOfAnotherScene) {
    Scene scene;
    scene.meshes.push_back(wall(-1.0f));
    scene.materials.resize(1);
    const SceneGeometry empty_geometry{Scene{}};
    BruteAccel accel;
    accel.build(empty_geometry.view(), {});
    EXPECT_THROW(SceneIntersector(scene, empty_geometry, accel), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
