// Formats read through assimp: OBJ triangles in file order with points and lines dropped, STL normals, node
// transforms and instancing (Collada; glTF's node hierarchy kept as instances), assimp's errors.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene_test_util.hpp"
#include "support/instanced_gltf.hpp"

namespace lancer {
namespace {

using test::corpus;
using test::kOrderVertices;

void expect_triangle_vertices(const TriangleMesh& mesh, std::size_t index, std::uint32_t a, std::uint32_t b,
                              std::uint32_t c) {
    ASSERT_LT(index, mesh.triangle_count());
    const Triangle triangle = mesh.triangle(index);
    EXPECT_EQ(triangle.v0, kOrderVertices[a]) << "triangle " << index;
    EXPECT_EQ(triangle.v1, kOrderVertices[b]) << "triangle " << index;
    EXPECT_EQ(triangle.v2, kOrderVertices[c]) << "triangle " << index;
}

TEST(AssimpLoader, ObjTrianglesComeInFileOrderWithoutLines) {
    const Scene scene = load_scene(corpus("good/order.obj"));
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    ASSERT_EQ(mesh.triangle_count(), 7u);
    // 1-based in the file.
    expect_triangle_vertices(mesh, 0, 0, 1, 2);
    expect_triangle_vertices(mesh, 1, 1, 3, 2);
    expect_triangle_vertices(mesh, 2, 3, 4, 5);
    expect_triangle_vertices(mesh, 3, 5, 0, 4);
    expect_triangle_vertices(mesh, 4, 2, 4, 1);
    // The quad, fanned from its first corner.
    expect_triangle_vertices(mesh, 5, 0, 1, 4);
    expect_triangle_vertices(mesh, 6, 0, 4, 3);
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

void expect_near(Vec3f got, Vec3f expected) {
    EXPECT_NEAR(got.x, expected.x, 1e-5f);
    EXPECT_NEAR(got.y, expected.y, 1e-5f);
    EXPECT_NEAR(got.z, expected.z, 1e-5f);
}

TEST(AssimpLoader, GltfMeshPlacedByThreeNodesIsOneInstancedMeshAndThreeInstances) {
    test::ScratchDir dir;
    const auto file = test::write_instanced_gltf(dir.path());
    const Scene flat = load_scene(file);
    const Scene placed = load_scene(file, {.keep_instances = true});
    // Flattened, as a World takes it: every placement a mesh of its own.
    ASSERT_EQ(flat.meshes.size(), 6u);
    EXPECT_TRUE(flat.instances.empty() && flat.instanced_meshes.empty());
    // Kept: mesh 0 once in its own frame and three instances; mesh 1 (placed once) and mesh 2 (a singular
    // placement) as meshes.
    ASSERT_EQ(placed.instanced_meshes.size(), 1u);
    ASSERT_EQ(placed.instances.size(), 3u);
    ASSERT_EQ(placed.meshes.size(), 3u);
    EXPECT_EQ(placed.instanced_meshes[0].triangle(0).v1, Vec3f(1.0f, 0.0f, 0.0f));
    EXPECT_EQ(placed.triangle_count(), 3u);
    EXPECT_EQ(placed.instanced_triangle_count(), 6u);
    EXPECT_EQ(flat.triangle_count(), 6u);
    // Depth-first placements: mesh 0 by nodes 0, 1 and 4 (the child of 2), mesh 1 by node 3, mesh 2 by 5 and
    // 6. Each instance puts mesh 0 where the flattened load put that placement; the rest are the same meshes.
    for (std::size_t i = 0; i < 3; ++i)
        EXPECT_EQ(placed.meshes[i].positions, flat.meshes[3 + i].positions) << i;
    const Triangle object = placed.instanced_meshes[0].triangle(0);
    for (std::size_t i = 0; i < placed.instances.size(); ++i) {
        EXPECT_EQ(placed.instances[i].mesh, 0u);
        const Transform& transform = placed.instances[i].object_to_world;
        const Triangle flattened = flat.meshes[i].triangle(0);
        expect_near(transform.point(object.v0), flattened.v0);
        expect_near(transform.point(object.v1), flattened.v1);
        expect_near(transform.point(object.v2), flattened.v2);
    }
    // The nested node: rotated a quarter turn about z after its child's translation (1, 0, 0), then moved
    // up 5.
    expect_near(placed.instances[2].object_to_world.point({0, 0, 0}), {0, 1, 5});
    expect_near(placed.instances[2].object_to_world.point({1, 0, 0}), {0, 2, 5});
    const Box3f bounds = placed.bounds(), flat_bounds = flat.bounds();
    expect_near(bounds.lo, flat_bounds.lo);
    expect_near(bounds.hi, flat_bounds.hi);
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
