// The corners of an object's 26-sided bounding polytope (src/accel/instance/bounding_polytope.hpp), whose
// mapped box is an instance's world box: the property that keeps that box conservative under any rotation.
// How the box follows the object's shape in a scene: instanced_scene_test.cpp.
#include "accel/instance/bounding_polytope.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "lancer/generate.hpp"
#include "lancer/scene.hpp"

namespace lancer {
namespace {

// What makes an instance's box hold every hit under any rotation: along every direction u the polytope's
// corners reach at least as far as the primitives grown by the tolerance, max u.p >= max u.x + tolerance
// |u|_1. A knot and spheres, held at scale 2^-3 as a structure would hold them; random directions and the
// slabs'.
TEST(BoundingPolytope, ReachesAsFarAsTheGrownPrimitivesAlongEveryDirection) {
    std::vector<Triangle> triangles = make_torus_knot(40, 8).triangles();
    std::vector<Sphere> spheres = {{{0.3f, -2.0f, 1.0f}, 0.7f, 0}, {{-1.5f, 0.2f, 0.4f}, 0.0f, 0}};
    const Box3f bounds = Geometry{triangles, spheres}.bounds();
    const double tolerance = 0.01;
    std::vector<Triangle> held = triangles;
    std::vector<Sphere> held_spheres = spheres;
    for (Triangle& t : held)
        t = {t.v0 * 0.125f, t.v1 * 0.125f, t.v2 * 0.125f};
    for (Sphere& sphere : held_spheres)
        sphere = {sphere.center * 0.125f, sphere.radius * 0.125f, 0};
    const std::vector<Vec3d> corners =
        top_level::bounding_polytope({held, held_spheres}, -3, bounds, tolerance);
    ASSERT_GE(corners.size(), 4u);
    EXPECT_LE(corners.size(), 96u);  // every update maps each of them
    std::vector<Vec3d> directions = top_level::polytope_normals();
    ASSERT_EQ(directions.size(), static_cast<std::size_t>(top_level::kPolytopePlanes));
    ASSERT_EQ(top_level::kPolytopePlanes, 26);
    std::mt19937 rng(9);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (int i = 0; i < 2000; ++i)
        directions.emplace_back(normal(rng), normal(rng), normal(rng));
    for (const Vec3d& u : directions) {
        double primitives = -kInfinity, reached = -kInfinity;
        for (const Triangle& t : triangles) {
            for (const Vec3f* v : {&t.v0, &t.v1, &t.v2})
                primitives = std::max(primitives, dot(u, Vec3d(*v)));
        }
        for (const Sphere& sphere : spheres)
            primitives =
                std::max(primitives, dot(u, Vec3d(sphere.center)) + sphere.radius * std::sqrt(dot(u, u)));
        for (const Vec3d& p : corners)
            reached = std::max(reached, dot(u, p));
        ASSERT_GE(reached, primitives + tolerance * (std::fabs(u.x) + std::fabs(u.y) + std::fabs(u.z)))
            << u.x << " " << u.y << " " << u.z;
    }
    EXPECT_TRUE(top_level::bounding_polytope({}, 0, bounds, tolerance).empty());
}

}  // namespace
}  // namespace lancer
