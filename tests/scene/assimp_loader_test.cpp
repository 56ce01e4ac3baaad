// Formats read through assimp: OBJ triangles in file order with points and lines dropped, STL normals, node
// transforms and instancing (Collada), assimp's errors.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene_test_util.hpp"

namespace lancer {
namespace {

using test::corpus;

// The six vertices of order.obj.
const std::vector<Vec3f> kVertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}, {2, 0, 0}};

void expect_triangle(const TriangleMesh& mesh, std::size_t index, std::uint32_t a, std::uint32_t b,
                     std::uint32_t c) {
    ASSERT_LT(index, mesh.triangle_count());
    const Triangle triangle = mesh.triangle(index);
    EXPECT_EQ(triangle.v0, kVertices[a]) << "triangle " << index;
    EXPECT_EQ(triangle.v1, kVertices[b]) << "triangle " << index;
    EXPECT_EQ(triangle.v2, kVertices[c]) << "triangle " << index;
}

TEST(AssimpLoader, ObjTrianglesComeInFileOrderWithoutLines) {
    const Scene scene = load_scene(corpus("good/order.obj"));
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    ASSERT_EQ(mesh.triangle_count(), 7u);
    // 1-based in the file.
    expect_triangle(mesh, 0, 0, 1, 2);
    expect_triangle(mesh, 1, 1, 3, 2);
    expect_triangle(mesh, 2, 3, 4, 5);
    expect_triangle(mesh, 3, 5, 0, 4);
    expect_triangle(mesh, 4, 2, 4, 1);
    // The quad, fanned from its first corner.
    expect_triangle(mesh, 5, 0, 1, 4);
    expect_triangle(mesh, 6, 0, 4, 3);
    EXPECT_FALSE(scene.camera.has_value());
    EXPECT_GE(scene.materials.size(), 1u);
}

TEST(AssimpLoader, StlKeepsFacetsAndNormals) {
    const Scene scene = load_scene(corpus("good/two_facets.stl"));
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    ASSERT_EQ(mesh.triangle_count(), 2u);
    EXPECT_EQ(mesh.triangle(1).v1, Vec3f(1.0f, 1.0f, 0.0f));
    ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
    for (const Vec3f& normal : mesh.normals)
        EXPECT_EQ(normal, Vec3f(0.0f, 0.0f, 1.0f));
}

TEST(AssimpLoader, EveryPlacementOfAMeshIsMovedByItsNode) {
    // One triangle placed twice: translated by (10, 0, 0), then scaled by 2 and translated by (0, 20, 0).
    const Scene scene = load_scene(corpus("good/instances.dae"));
    ASSERT_EQ(scene.meshes.size(), 2u);
    EXPECT_EQ(scene.meshes[0].triangle(0).v0, Vec3f(10.0f, 0.0f, 0.0f));
    EXPECT_EQ(scene.meshes[0].triangle(0).v1, Vec3f(11.0f, 0.0f, 0.0f));
    EXPECT_EQ(scene.meshes[0].triangle(0).v2, Vec3f(10.0f, 1.0f, 0.0f));
    EXPECT_EQ(scene.meshes[1].triangle(0).v0, Vec3f(0.0f, 20.0f, 0.0f));
    EXPECT_EQ(scene.meshes[1].triangle(0).v1, Vec3f(2.0f, 20.0f, 0.0f));
    EXPECT_EQ(scene.meshes[1].triangle(0).v2, Vec3f(0.0f, 22.0f, 0.0f));
}

TEST(AssimpLoader, ReportsAssimpsErrorWithTheFileName) {
    test::ScratchDir dir;
    const auto file = dir.write("empty.obj", "");
    try {
        (void)load_scene(file);
        ADD_FAILURE() << "no LoadError";
    } catch (const LoadError& error) {
        EXPECT_EQ(error.file(), file);
        EXPECT_EQ(error.line(), 0u);
        EXPECT_EQ(std::string(error.what()).rfind(file.string() + ": assimp: ", 0), 0u) << error.what();
    }
}

}  // namespace
}  // namespace lancer
