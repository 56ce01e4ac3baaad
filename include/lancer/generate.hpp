// Procedural meshes: closed, watertight test objects and stand-ins for the Stanford meshes when absent.
#pragma once

#include <vector>

#include "lancer/scene.hpp"
#include "lancer/transform.hpp"

namespace lancer {

// Subdivided icosahedron projected on the sphere: 20 * 4^subdivisions triangles, closed (every edge shared
// by exactly two triangles, vertices shared by index), outward counter-clockwise winding, vertex normals.
[[nodiscard]] TriangleMesh make_icosphere(int subdivisions, Vec3f center = Vec3f(0.0f), float radius = 1.0f);

// `mesh` with each triangle split into four at its edges' midpoints (Loop's pattern without the smoothing):
// an edge's midpoint is one vertex shared by the triangles of the edge, numbered in the order the triangles
// first meet it, so a closed mesh stays closed; vertex normals, where given, are the normalised sums of the
// edge's two; a triangle's material id goes to its four. The larger meshes of `lancer bench --subdivide`.
[[nodiscard]] TriangleMesh subdivided(const TriangleMesh& mesh);

// A (p, q) torus knot swept by a circle: a closed tube of 2 * segments * sides triangles with vertex
// normals. About 70k, 350k and 870k triangles for segments = 1750, 8750, 21800 with 20 sides.
[[nodiscard]] TriangleMesh make_torus_knot(int segments, int sides, int p = 2, int q = 3,
                                           float tube_radius = 0.15f);

// `count` placements of an object of box `bounds` (`lancer bench --instances`, `lancer render --instances`):
// each a random rotation, a uniform scale in [0.5, 1.5] and a position in a cube whose side grows as the cube
// root of `count`, so that the instances fill it about as densely whatever the count and rays cross many of
// them. Fixed seed: the same placements on every run and under every compiler. Each placement draws, from
// std::mt19937(2026) in this order, its rotation axis (z + 0.01, y, x, each uniform in [-1, 1]), its scale,
// its angle (uniform in [0, 6.2831853]) and its position (x, y, z, each side times uniform in [-1, 1]).
[[nodiscard]] std::vector<Transform> random_placements(const Box3f& bounds, int count);

}  // namespace lancer
