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

// `count` random triangles, each with a corner in [0, extent)^3 and its other corners within `size` of it:
// size `large` for every `large_every`-th triangle, `small` for the others. It draws from `rng`, so that a
// scene maker can go on drawing after it.
inline void append_triangle_soup(std::mt19937& rng, int count, float extent, int large_every, float large,
                                 float small, std::vector<Triangle>& triangles) {
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    auto point = [&](float scale) { return Vec3f(unit(rng), unit(rng), unit(rng)) * scale; };
    for (int i = 0; i < count; ++i) {
        const Vec3f base = point(extent);
        const float size = i % large_every == 0 ? large : small;
        triangles.push_back(
            {base, base + point(size) - Vec3f(size / 2), base + point(size) - Vec3f(size / 2)});
    }
}

// The square [0, side]^2 of the plane z = 0 cut into unit squares of two triangles each: every triangle in
// one plane, each inner vertex shared by six of them.
inline std::vector<Triangle> planar_grid_triangles(int side) {
    std::vector<Triangle> triangles;
    for (int i = 0; i < side; ++i) {
        for (int j = 0; j < side; ++j) {
            const float x = static_cast<float>(i), y = static_cast<float>(j);
            triangles.push_back({{x, y, 0}, {x + 1, y, 0}, {x + 1, y + 1, 0}});
            triangles.push_back({{x, y, 0}, {x + 1, y + 1, 0}, {x, y + 1, 0}});
        }
    }
    return triangles;
}

// An icosphere of 3 subdivisions (1280 triangles) at `center`, a torus knot of 2 * segments * sides triangles
// around it and `spheres` spheres in [-2, 2)^3 of radius 0.05 to 0.25, drawn from `rng`: large and small
// primitives of both kinds, overlapping.
inline TestScene icosphere_knot_and_spheres(std::mt19937& rng, Vec3f center, int segments, int sides,
                                            int spheres) {
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    TestScene scene{"icosphere, knot and spheres", {}, {}};
    make_icosphere(3, center, 1.0f).append_triangles(scene.triangles);
    make_torus_knot(segments, sides).append_triangles(scene.triangles);
    for (int i = 0; i < spheres; ++i) {
        const Vec3f position = Vec3f(unit(rng), unit(rng), unit(rng)) * 4.0f - Vec3f(2.0f);
        scene.spheres.push_back({position, 0.05f + 0.2f * unit(rng), 0});
    }
    return scene;
}

// A triangle reaching `reach` from the origin in the plane z = 0.5, and `tiny` triangles of side 1e-3 in the
// unit cube (corners drawn from `rng`): leaves of very different levels side by side.
inline TestScene huge_triangle_next_to_tiny_ones(std::mt19937& rng, float reach, int tiny) {
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    TestScene scene{"huge triangle next to tiny ones", {}, {}};
    scene.triangles.push_back({{-reach, -reach, 0.5f}, {reach, -reach, 0.5f}, {0, reach, 0.5f}});
    for (int i = 0; i < tiny; ++i) {
        const Vec3f base(unit(rng), unit(rng), unit(rng));
        scene.triangles.push_back({base, base + Vec3f(1e-3f, 0, 0), base + Vec3f(0, 1e-3f, 1e-4f)});
    }
    return scene;
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
