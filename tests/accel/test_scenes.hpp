// What the structure tests share to make scenes: loose triangles and spheres, as a Geometry sees them.
#pragma once

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

// Appends the mesh's triangles in file order.
inline void append(std::vector<Triangle>& triangles, const TriangleMesh& mesh) {
    for (std::size_t i = 0; i < mesh.triangle_count(); ++i)
        triangles.push_back(mesh.triangle(i));
}

// A torus knot of 2 * segments * 12 triangles.
inline std::vector<Triangle> knot_triangles(int segments) {
    std::vector<Triangle> triangles;
    append(triangles, make_torus_knot(segments, 12));
    return triangles;
}

}  // namespace lancer::testing
