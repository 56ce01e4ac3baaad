// What the structure tests share to make scenes: loose triangles and spheres, as a Geometry sees them.
#pragma once

#include <random>
#include <string>
#include <vector>

#include "lancer/generate.hpp"
#include "lancer/scene.hpp"

namespace lancer::testing {

struct TestScene {
    std::string name;
    std::vector<Triangle> triangles;
    std::vector<Sphere> spheres;

    [[nodiscard]] Geometry geometry() const { return {triangles, spheres}; }
};

// A torus knot of 2 * segments * 12 triangles.
inline std::vector<Triangle> knot_triangles(int segments) {
    return make_torus_knot(segments, 12).triangles();
}

// Small triangles spread in a 100-unit cube, and long thin ones along its diagonal: the long ones' boxes
// inflate every BVH node that holds them, whatever object split is made, while planes that cut them into
// short pieces keep the nodes tight (the case spatial splits are for: Stich, Friedrich & Dietrich 2009).
inline std::vector<Triangle> small_and_long_triangles(int small, int long_ones) {
    std::mt19937 rng(12);
    std::uniform_real_distribution<float> offset(0.0f, 100.0f);
    std::vector<Triangle> triangles;
    for (int i = 0; i < small; ++i) {
        const Vec3f corner(offset(rng), offset(rng), offset(rng));
        triangles.push_back({corner, corner + Vec3f(1, 0, 0), corner + Vec3f(0, 1, 1)});
    }
    for (int i = 0; i < long_ones; ++i) {
        const Vec3f start(offset(rng), offset(rng), 0.0f);
        const Vec3f end = start + Vec3f(100.0f);
        triangles.push_back({start, end, end + Vec3f(0.5f, -0.5f, 0.0f)});
    }
    return triangles;
}

// The case that separates an exact leaf-to-leaf walk from one that returns at the first leaf with a hit:
// triangle 0 is slanted, crosses `ray` at x = 3.5 and spans x in [0, 10], so the first leaves reference it
// and find its hit beyond their exit; triangle 1, across the ray at x = 3 in a later leaf, is the closest.
struct HitBeyondLeafExit {
    TestScene scene{"hit beyond the leaf exit",
                    {{{0, -2, 0.3f - 0.35f}, {10, -2, 0.3f + 0.65f}, {0, 2, 0.3f - 0.35f}},
                     {{3, 0.2f, 0.2f}, {3, 0.5f, 0.2f}, {3, 0.2f, 0.5f}}},
                    {}};
    Ray ray{{-1, 0.3f, 0.3f}, {1, 0, 0}, 0.0f, kInfinity};
};

}  // namespace lancer::testing
