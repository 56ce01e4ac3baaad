// The NFF reader on a file with every keyword: view, background, lights, the material mapping, spheres,
// polygons (convex and concave), patches with normals, and the tessellated cylinders and cones.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene_test_util.hpp"

namespace lancer {
namespace {

using test::corpus;

// every_keyword.nff, primitive by primitive: the square (2 triangles), the patch (1), the cylinder and the
// inside-visible cone (48 each), then the L (4).
constexpr std::size_t kSquare = 0, kPatch = 2, kCylinder = 3, kCone = 51, kL = 99, kTriangles = 103;
constexpr std::size_t kConeTriangles = 48;

float area(const Triangle& triangle) {
    return length(triangle.geometric_normal()) / 2.0f;
}

// The point of the axis from `base` along `axis` (unit) nearest to `p`.
Vec3f axis_point(Vec3f p, Vec3f base, Vec3f axis) {
    return base + dot(p - base, axis) * axis;
}

class EveryKeyword : public ::testing::Test {
  protected:
    void SetUp() override {
        scene_ = load_scene(corpus("good/every_keyword.nff"));
        ASSERT_EQ(scene_.meshes.size(), 1u);
        ASSERT_EQ(scene_.meshes[0].triangle_count(), kTriangles);
    }
    [[nodiscard]] const TriangleMesh& mesh() const { return scene_.meshes[0]; }
    [[nodiscard]] Vec3f normal_at(std::size_t triangle, int corner) const {
        return mesh().normals[mesh().indices[3 * triangle + static_cast<std::size_t>(corner)]];
    }

    Scene scene_;
};

TEST_F(EveryKeyword, ReadsViewBackgroundAndLights) {
    ASSERT_TRUE(scene_.camera.has_value());
    const Camera& camera = *scene_.camera;
    EXPECT_EQ(camera.eye, Vec3f(1.0f, -8.0f, 3.0f));
    EXPECT_EQ(camera.look_at, Vec3f(0.0f, 0.0f, 0.5f));
    EXPECT_EQ(camera.up, Vec3f(0.0f, 0.0f, 1.0f));
    EXPECT_EQ(camera.vertical_fov_degrees, 40.0f);
    EXPECT_EQ(camera.width, 320);
    EXPECT_EQ(camera.height, 200);
    EXPECT_EQ(scene_.background, Vec3f(0.1f, 0.2f, 0.3f));
    ASSERT_EQ(scene_.lights.size(), 2u);
    EXPECT_EQ(scene_.lights[0].position, Vec3f(10.0f));
    // The SPD's sqrt(N) / (2N) for N = 2 lights, for the light without a colour and for the ambient light.
    EXPECT_EQ(scene_.lights[0].color, Vec3f(std::sqrt(2.0f) / 4.0f));
    EXPECT_EQ(scene_.lights[1].position, Vec3f(-10.0f, 5.0f, 5.0f));
    EXPECT_EQ(scene_.lights[1].color, Vec3f(0.5f, 0.25f, 1.0f));
    EXPECT_EQ(scene_.ambient, Vec3f(std::sqrt(2.0f) / 4.0f));
}

TEST(NffExtensions, PlaneAndAmbient) {
    test::ScratchDir dir;
    const auto file = dir.write("plane.nff",
                                "ambient 0.2 0.3 0.4\nl 0 5 0\nf 1 1 1 1 0 0 0 1\nplane 0 2 0 -4 checkered\n"
                                "f 1 0 0 1 0 0 0 1\nplane 1 0 0 3\n");
    const Scene scene = load_scene(file);
    EXPECT_EQ(scene.ambient, Vec3f(0.2f, 0.3f, 0.4f));
    EXPECT_EQ(scene.lights[0].color, Vec3f(0.5f));  // one light: sqrt(1) / 2
    ASSERT_EQ(scene.planes.size(), 2u);
    EXPECT_EQ(scene.planes[0].normal, Vec3f(0.0f, 1.0f, 0.0f));
    EXPECT_EQ(scene.planes[0].offset, -2.0f);
    EXPECT_TRUE(scene.planes[0].checkered);
    EXPECT_EQ(scene.planes[0].material, 0u);
    EXPECT_EQ(scene.planes[1].normal, Vec3f(1.0f, 0.0f, 0.0f));
    EXPECT_EQ(scene.planes[1].offset, 3.0f);
    EXPECT_FALSE(scene.planes[1].checkered);
    EXPECT_EQ(scene.planes[1].material, 1u);
}

TEST(NffExtensions, PlaneWithoutNormalIsAnError) {
    test::ScratchDir dir;
    const auto file = dir.write("flat.nff", "plane 0 0 0 1\n");
    EXPECT_THROW((void)load_scene(file), LoadError);
}

TEST_F(EveryKeyword, MapsEachMaterialLineAndGivesItToTheFollowingPrimitives) {
    ASSERT_EQ(scene_.materials.size(), 2u);
    const Material& red = scene_.materials[0];
    EXPECT_EQ(red.color, Vec3f(1.0f, 0.0f, 0.0f));
    EXPECT_FLOAT_EQ(red.kd, 0.7f);
    EXPECT_FLOAT_EQ(red.ks, 0.3f);
    EXPECT_EQ(red.shininess, 20.0f);
    EXPECT_EQ(red.kt, 0.0f);
    EXPECT_EQ(red.ior, 1.0f);
    EXPECT_FALSE(red.two_sided);
    const Material& glass = scene_.materials[1];
    EXPECT_EQ(glass.color, Vec3f(0.0f, 1.0f, 0.0f));
    EXPECT_FLOAT_EQ(glass.kd, 0.5f);
    EXPECT_FLOAT_EQ(glass.ks, 0.2f);
    EXPECT_EQ(glass.shininess, 100000.0f);
    EXPECT_FLOAT_EQ(glass.kt, 0.8f);
    EXPECT_FLOAT_EQ(glass.ior, 1.5f);
    EXPECT_TRUE(glass.two_sided);

    ASSERT_EQ(scene_.spheres.size(), 1u);
    EXPECT_EQ(scene_.spheres[0].material, 0u);
    ASSERT_EQ(mesh().material_ids.size(), kTriangles);
    for (std::size_t i = 0; i < kTriangles; ++i)
        EXPECT_EQ(mesh().material_ids[i], i < kPatch ? 0u : 1u) << i;
}

TEST_F(EveryKeyword, ReadsTheSphere) {
    EXPECT_EQ(scene_.spheres[0].center, Vec3f(0.0f, 0.0f, 1.0f));
    EXPECT_EQ(scene_.spheres[0].radius, 0.5f);
}

TEST_F(EveryKeyword, ConvexPolygonIsAFanFacingItsCounterClockwiseSide) {
    EXPECT_EQ(mesh().triangle(kSquare).v0, Vec3f(0.0f, 0.0f, 0.0f));
    EXPECT_EQ(mesh().triangle(kSquare).v2, Vec3f(1.0f, 1.0f, 0.0f));
    EXPECT_EQ(mesh().triangle(kSquare + 1).v2, Vec3f(0.0f, 1.0f, 0.0f));
    for (std::size_t t = kSquare; t < kSquare + 2; ++t) {
        EXPECT_EQ(normalize(mesh().triangle(t).geometric_normal()), Vec3f(0.0f, 0.0f, 1.0f));
        // The file has patches, so polygon vertices get their face normal.
        for (int corner = 0; corner < 3; ++corner)
            EXPECT_EQ(normal_at(t, corner), Vec3f(0.0f, 0.0f, 1.0f));
    }
}

TEST_F(EveryKeyword, PatchKeepsItsNormalsNormalised) {
    const Triangle patch = mesh().triangle(kPatch);
    EXPECT_EQ(patch.v0, Vec3f(0.0f, 0.0f, 1.0f));
    EXPECT_EQ(patch.v1, Vec3f(1.0f, 0.0f, 1.0f));
    EXPECT_EQ(patch.v2, Vec3f(0.0f, 1.0f, 1.0f));
    for (int corner = 0; corner < 3; ++corner)
        EXPECT_EQ(normal_at(kPatch, corner), Vec3f(0.0f, 0.0f, 1.0f));
}

TEST_F(EveryKeyword, CylinderIsTessellatedOnItsSurfaceFacingOutwards) {
    const Vec3f base{0.0f, 0.0f, 0.0f}, axis{0.0f, 0.0f, 1.0f};
    Box3f bounds;
    float total_area = 0.0f;
    for (std::size_t t = kCylinder; t < kCylinder + kConeTriangles; ++t) {
        const Triangle triangle = mesh().triangle(t);
        bounds.extend(triangle.bounds());
        total_area += area(triangle);
        const Vec3f centroid = (triangle.v0 + triangle.v1 + triangle.v2) / 3.0f;
        const Vec3f outward = centroid - axis_point(centroid, base, axis);
        EXPECT_GT(dot(triangle.geometric_normal(), outward), 0.0f) << t;
        for (int corner = 0; corner < 3; ++corner) {
            const Vec3f p = corner == 0 ? triangle.v0 : (corner == 1 ? triangle.v1 : triangle.v2);
            const Vec3f radial = p - axis_point(p, base, axis);
            EXPECT_NEAR(length(radial), 1.0f, 1e-6f);
            // A cylinder's smooth normal is the unit radial direction.
            const Vec3f normal = normal_at(t, corner);
            EXPECT_NEAR(normal.x, radial.x, 1e-6f);
            EXPECT_NEAR(normal.y, radial.y, 1e-6f);
            EXPECT_NEAR(normal.z, 0.0f, 1e-6f);
        }
    }
    EXPECT_NEAR(bounds.lo.x, -1.0f, 1e-6f);
    EXPECT_NEAR(bounds.lo.y, -1.0f, 1e-6f);
    EXPECT_EQ(bounds.lo.z, 0.0f);
    EXPECT_NEAR(bounds.hi.x, 1.0f, 1e-6f);
    EXPECT_NEAR(bounds.hi.y, 1.0f, 1e-6f);
    EXPECT_EQ(bounds.hi.z, 2.0f);
    // 24 rectangles inscribed in the circle: height 2 times the 24-gon's perimeter 48 sin(pi / 24).
    EXPECT_NEAR(total_area, 2.0f * 48.0f * std::sin(3.14159265f / 24.0f), 1e-4f);
}

TEST_F(EveryKeyword, NegativeRadiiGiveAConeSeenFromInside) {
    const Vec3f base{5.0f, 0.0f, 0.0f}, axis{0.0f, 0.0f, 1.0f};
    // c 5 0 0 -1 5 0 4 -0.5: the outward normal leans up by atan(0.5 / 4); inside, it is reversed.
    const Vec3f outward_slope = normalize(Vec3f(4.0f, 0.0f, 0.5f));
    for (std::size_t t = kCone; t < kCone + kConeTriangles; ++t) {
        const Triangle triangle = mesh().triangle(t);
        const Vec3f centroid = (triangle.v0 + triangle.v1 + triangle.v2) / 3.0f;
        const Vec3f outward = centroid - axis_point(centroid, base, axis);
        EXPECT_LT(dot(triangle.geometric_normal(), outward), 0.0f) << t;
        for (int corner = 0; corner < 3; ++corner) {
            const Vec3f normal = normal_at(t, corner);
            EXPECT_GT(dot(normal, triangle.geometric_normal()), 0.0f) << t;
            EXPECT_NEAR(normal.z, -outward_slope.z, 1e-6f);
            EXPECT_NEAR(length(normal), 1.0f, 1e-6f);
        }
        for (const Vec3f p : {triangle.v0, triangle.v1, triangle.v2}) {
            const float radius = length(p - axis_point(p, base, axis));
            EXPECT_NEAR(radius, p.z == 0.0f ? 1.0f : 0.5f, 1e-6f);
        }
    }
}

TEST_F(EveryKeyword, ConcavePolygonKeepsItsAreaAndWinding) {
    float total_area = 0.0f;
    for (std::size_t t = kL; t < kTriangles; ++t) {
        const Triangle triangle = mesh().triangle(t);
        total_area += area(triangle);
        // The L runs counter-clockwise seen from +y: every triangle must face +y.
        const Vec3f normal = normalize(triangle.geometric_normal());
        EXPECT_NEAR(normal.y, 1.0f, 1e-6f) << t;
        for (const Vec3f p : {triangle.v0, triangle.v1, triangle.v2})
            EXPECT_EQ(p.y, -2.0f);
    }
    EXPECT_NEAR(total_area, 3.0f, 1e-6f);
}

TEST(NffLoader, PrimitivesBeforeAnyMaterialGetTheDefaultOne) {
    test::ScratchDir dir;
    const auto file = dir.write("plain.nff", "s 0 0 0 1\np 3 0 0 0 1 0 0 0 1 0\n");
    const Scene scene = load_scene(file);
    ASSERT_EQ(scene.materials.size(), 1u);
    const Material default_material;
    EXPECT_EQ(scene.materials[0].color, default_material.color);
    EXPECT_EQ(scene.materials[0].kd, default_material.kd);
    EXPECT_EQ(scene.spheres[0].material, 0u);
    ASSERT_EQ(scene.meshes.size(), 1u);
    // A mesh whose triangles share one material carries it once, and polygons alone need no normals.
    EXPECT_TRUE(scene.meshes[0].material_ids.empty());
    EXPECT_EQ(scene.meshes[0].material, 0u);
    EXPECT_TRUE(scene.meshes[0].normals.empty());
    EXPECT_FALSE(scene.camera.has_value());
    EXPECT_EQ(scene.background, Vec3f(0.0f));
}

TEST(NffLoader, PointedConeLeavesOutTheFlatTriangles) {
    test::ScratchDir dir;
    const auto file = dir.write("cone.nff", "c 0 0 0 1 0 0 1 0\n");
    const Scene scene = load_scene(file);
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    ASSERT_EQ(mesh.triangle_count(), 24u);
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const Triangle triangle = mesh.triangle(t);
        EXPECT_GT(area(triangle), 0.0f) << t;
        const Vec3f centroid = (triangle.v0 + triangle.v1 + triangle.v2) / 3.0f;
        EXPECT_GT(dot(triangle.geometric_normal(), Vec3f(centroid.x, centroid.y, 0.0f)), 0.0f) << t;
    }
}

TEST(NffLoader, KeepsPatchesWithAZeroNormalUsable) {
    test::ScratchDir dir;
    const auto file = dir.write("patch.nff", "pp 3\n0 0 0 0 0 0\n1 0 0 0 0 1\n0 1 0 0 0 1\n");
    const Scene scene = load_scene(file);
    ASSERT_EQ(scene.meshes.size(), 1u);
    EXPECT_EQ(scene.meshes[0].normals[0], Vec3f(0.0f, 0.0f, 1.0f));
}

}  // namespace
}  // namespace lancer
