// check_scene on scenes made in code: each invariant of scene.hpp broken once, each named in the message.
#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>
#include <string>

#include "lancer/scene.hpp"

namespace lancer {
namespace {

// One triangle, one sphere, one plane, one material: valid.
Scene valid_scene() {
    Scene scene;
    TriangleMesh mesh;
    mesh.name = "quad";
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    mesh.indices = {0, 1, 2};
    scene.meshes.push_back(mesh);
    scene.spheres.push_back({{0, 0, 3}, 0.5f, 0});
    scene.planes.push_back({{0, 1, 0}, -1.0f, 0});
    scene.materials.emplace_back();
    return scene;
}

std::string message_of(const Scene& scene) {
    try {
        check_scene(scene);
    } catch (const std::invalid_argument& error) {
        return error.what();
    }
    return "";
}

TEST(CheckScene, AcceptsAValidScene) {
    EXPECT_NO_THROW(check_scene(valid_scene()));
}

TEST(CheckScene, NamesEachBrokenInvariant) {
    const std::pair<std::function<void(Scene&)>, std::string> cases[] = {
        {[](Scene& s) { s.meshes[0].positions[1].x = 0x1p62f; },
         "mesh 'quad' has a vertex outside the coordinate domain"},
        {[](Scene& s) { s.meshes[0].indices.push_back(0); },
         "mesh 'quad' has an index count that is not a multiple of 3"},
        {[](Scene& s) { s.meshes[0].indices[2] = 3; }, "mesh 'quad' has a vertex index out of range"},
        {[](Scene& s) {
             s.meshes[0].normals = {{0, 0, 1}};
         },
         "mesh 'quad' has 1 normals for 3 vertices"},
        {[](Scene& s) {
             s.meshes[0].material_ids = {0, 0};
         },
         "mesh 'quad' has 2 material ids for 1 triangles"},
        {[](Scene& s) { s.meshes[0].material = 1; }, "mesh 'quad' uses material 1, but the scene has 1"},
        {[](Scene& s) { s.meshes[0].material_ids = {2}; }, "triangle 0 of mesh 'quad' uses material 2"},
        {[](Scene& s) { s.spheres[0].material = 5; }, "a sphere uses material 5"},
        {[](Scene& s) { s.spheres[0].radius = 0x1p62f; }, "a sphere reaches outside the coordinate domain"},
        {[](Scene& s) { s.planes[0].material = 1; }, "a plane uses material 1"},
        {[](Scene& s) { s.materials.clear(); }, "uses material 0, but the scene has 0"},
    };
    for (const auto& [breaks, expected] : cases) {
        Scene scene = valid_scene();
        breaks(scene);
        EXPECT_NE(message_of(scene).find(expected), std::string::npos)
            << "expected \"" << expected << "\", got \"" << message_of(scene) << "\"";
    }
}

}  // namespace
}  // namespace lancer
