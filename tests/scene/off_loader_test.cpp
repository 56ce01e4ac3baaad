// The OFF reader: fan triangulation in file order (the triangle numbers `lancer rays` reports), comments,
// extra columns, and the header forms found in the wild.
#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene_test_util.hpp"

namespace lancer {
namespace {

using test::corpus;

std::vector<std::array<std::uint32_t, 3>> triangles_of(const TriangleMesh& mesh) {
    std::vector<std::array<std::uint32_t, 3>> triangles;
    for (std::size_t i = 0; i < mesh.triangle_count(); ++i) {
        triangles.push_back({mesh.indices[3 * i], mesh.indices[3 * i + 1], mesh.indices[3 * i + 2]});
    }
    return triangles;
}

TEST(OffLoader, FansPolygonsAndNumbersTrianglesInFileOrder) {
    const Scene scene = load_scene(corpus("good/quad_pentagon.off"));
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    EXPECT_EQ(mesh.name, "quad_pentagon");
    EXPECT_EQ(mesh.positions.size(), 9u);
    EXPECT_EQ(mesh.positions[6], Vec3f(3.5f, 1.0f, 0.0f));
    // Quad 0 1 2 3, triangle 1 4 7, pentagon 4 5 6 7 8: fans (i0, ik, ik+1), one face after the other.
    const std::vector<std::array<std::uint32_t, 3>> expected = {{0, 1, 2}, {0, 2, 3}, {1, 4, 7},
                                                                {4, 5, 6}, {4, 6, 7}, {4, 7, 8}};
    EXPECT_EQ(triangles_of(mesh), expected);
    EXPECT_TRUE(mesh.normals.empty());
    EXPECT_TRUE(mesh.material_ids.empty());
    EXPECT_EQ(mesh.material, 0u);
    EXPECT_EQ(scene.materials.size(), 1u);
    EXPECT_FALSE(scene.camera.has_value());
    EXPECT_TRUE(scene.spheres.empty());
    EXPECT_TRUE(scene.lights.empty());
}

TEST(OffLoader, SkipsCommentsBlankLinesAndExtraColumns) {
    const Scene scene = load_scene(corpus("good/comments_colours.off"));
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    const std::vector<Vec3f> expected_positions = {
        {0.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {1.5f, 2.5f, -0.5f}, {-1.0f, 2.0f, 0.25f}};
    EXPECT_EQ(mesh.positions, expected_positions);
    const std::vector<std::array<std::uint32_t, 3>> expected = {{0, 1, 2}, {0, 2, 3}};
    EXPECT_EQ(triangles_of(mesh), expected);
}

TEST(OffLoader, ReadsCountsOnTheMagicLineWithoutEdgeCountAndCrLf) {
    const Scene scene = load_scene(corpus("good/counts_on_magic_line_crlf.off"));
    ASSERT_EQ(scene.meshes.size(), 1u);
    EXPECT_EQ(scene.meshes[0].positions.size(), 3u);
    EXPECT_EQ(scene.meshes[0].triangle_count(), 1u);
    EXPECT_EQ(scene.meshes[0].triangle(0).v1, Vec3f(1.0f, 0.0f, 0.0f));
}

TEST(OffLoader, ExtensionIsMatchedWithoutCase) {
    test::ScratchDir dir;
    const auto file = dir.write("UPPER.OFF", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(load_scene(file).triangle_count(), 1u);
}

TEST(OffLoader, KeepsAFileWithoutFacesAsAnEmptyMesh) {
    test::ScratchDir dir;
    const auto file = dir.write("points.off", "OFF\n2 0 0\n0 0 0\n1 1 1\n");
    const Scene scene = load_scene(file);
    ASSERT_EQ(scene.meshes.size(), 1u);
    EXPECT_EQ(scene.meshes[0].positions.size(), 2u);
    EXPECT_EQ(scene.triangle_count(), 0u);
}

TEST(OffLoader, TinyNumbersUnderflowToZeroInsteadOfFailing) {
    test::ScratchDir dir;
    const auto file = dir.write("tiny.off", "OFF\n3 1 0\n1e-50 0 0\n1 0 0\n0 1 -1e-60\n3 0 1 2\n");
    const Scene scene = load_scene(file);
    EXPECT_EQ(scene.meshes[0].positions[0].x, 0.0f);
    EXPECT_EQ(scene.meshes[0].positions[2].z, 0.0f);
}

}  // namespace
}  // namespace lancer
