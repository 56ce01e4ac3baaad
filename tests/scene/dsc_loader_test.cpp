// The seed-003 .dsc reader: material mapping, lights, one material per .off face, the canonical camera.
#include <gtest/gtest.h>

#include <vector>

#include "lancer/load_scene.hpp"
#include "scene_test_util.hpp"

namespace lancer {
namespace {

using test::corpus;

TEST(DscLoader, MapsMaterialsLightsFaceMaterialsAndCamera) {
    const Scene scene = load_scene(corpus("good/scene.dsc"));

    ASSERT_EQ(scene.materials.size(), 3u);
    // 1 0 0 0.3 0.2 1.5: refracting, so the transmission weight is what kd and ks leave.
    const Material& glass = scene.materials[0];
    EXPECT_EQ(glass.color, Vec3f(1.0f, 0.0f, 0.0f));
    EXPECT_FLOAT_EQ(glass.ks, 0.3f);
    EXPECT_FLOAT_EQ(glass.kd, 0.2f);
    EXPECT_FLOAT_EQ(glass.ior, 1.5f);
    EXPECT_FLOAT_EQ(glass.kt, 0.5f);
    EXPECT_TRUE(glass.two_sided);
    // 0 1 0 0.5 0.5 1: index 1 does not refract.
    const Material& plain = scene.materials[1];
    EXPECT_EQ(plain.color, Vec3f(0.0f, 1.0f, 0.0f));
    EXPECT_FLOAT_EQ(plain.ks, 0.5f);
    EXPECT_FLOAT_EQ(plain.kd, 0.5f);
    EXPECT_EQ(plain.kt, 0.0f);
    EXPECT_FALSE(plain.two_sided);
    // 0 0 1 0.1 0.9 0: index 0 means "not given".
    EXPECT_EQ(scene.materials[2].kt, 0.0f);
    EXPECT_FLOAT_EQ(scene.materials[2].kd, 0.9f);

    ASSERT_EQ(scene.lights.size(), 2u);
    EXPECT_EQ(scene.lights[0].position, Vec3f(0.0f, 0.0f, 10.0f));
    EXPECT_EQ(scene.lights[0].color, Vec3f(1.0f));
    EXPECT_EQ(scene.lights[1].position, Vec3f(5.0f));
    EXPECT_EQ(scene.lights[1].color, Vec3f(0.5f, 0.25f, 0.125f));

    // Faces: a quad (two fan triangles) with material 2, then triangles with 0 and 1.
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    EXPECT_EQ(mesh.name, "scene");
    ASSERT_EQ(mesh.triangle_count(), 4u);
    EXPECT_EQ(mesh.material_ids, (std::vector<std::uint32_t>{2, 2, 0, 1}));

    ASSERT_TRUE(scene.camera.has_value());
    const Camera expected = canonical_view({{-1.0f, -1.0f, 0.0f}, {1.0f, 1.0f, 2.0f}}, 320, 240);
    EXPECT_EQ(scene.camera->eye, expected.eye);
    EXPECT_EQ(scene.camera->look_at, expected.look_at);
    EXPECT_EQ(scene.camera->up, expected.up);
    EXPECT_EQ(scene.camera->vertical_fov_degrees, expected.vertical_fov_degrees);
    EXPECT_EQ(scene.camera->width, 320);
    EXPECT_EQ(scene.camera->height, 240);
}

TEST(DscLoader, OneMaterialForAllFacesBecomesTheMeshMaterial) {
    test::ScratchDir dir;
    (void)dir.write("uniform.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n");
    const auto file = dir.write("uniform.dsc", "DSC\n8 8\n2 0\n1 1 1 0 1 1\n1 0 0 0 1 1\n2\n1\n1\n");
    const Scene scene = load_scene(file);
    ASSERT_EQ(scene.meshes.size(), 1u);
    EXPECT_TRUE(scene.meshes[0].material_ids.empty());
    EXPECT_EQ(scene.meshes[0].material, 1u);
}

TEST(DscLoader, ErrorsInsideTheOffNameTheOff) {
    test::ScratchDir dir;
    const auto off = dir.write("bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n");
    const auto file = dir.write("bad.dsc", "DSC\n8 8\n1 0\n1 1 1 0 1 1\n1\n0\n");
    test::expect_load_error(file, 6, "face index 9 out of range [0, 3)", off);
}

}  // namespace
}  // namespace lancer
