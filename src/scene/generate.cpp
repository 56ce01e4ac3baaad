#include "lancer/generate.hpp"

#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <utility>

namespace lancer {

TriangleMesh make_icosphere(int subdivisions, Vec3f center, float radius) {
    // The 12 vertices of an icosahedron: cyclic permutations of (0, +-1, +-phi).
    const float phi = (1.0f + std::sqrt(5.0f)) / 2.0f;
    std::vector<Vec3f> unit = {{-1, phi, 0}, {1, phi, 0}, {-1, -phi, 0}, {1, -phi, 0},
                               {0, -1, phi}, {0, 1, phi}, {0, -1, -phi}, {0, 1, -phi},
                               {phi, 0, -1}, {phi, 0, 1}, {-phi, 0, -1}, {-phi, 0, 1}};
    for (Vec3f& p : unit)
        p = normalize(p);
    std::vector<std::uint32_t> indices = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                                          4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                                          6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
    for (int level = 0; level < subdivisions; ++level) {
        // One midpoint per edge, shared by the two triangles of the edge: the mesh stays closed.
        std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoints;
        auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
            const auto key = std::minmax(a, b);
            auto [it, inserted] = midpoints.try_emplace(key, static_cast<std::uint32_t>(unit.size()));
            if (inserted) unit.push_back(normalize(unit[a] + unit[b]));
            return it->second;
        };
        std::vector<std::uint32_t> finer;
        finer.reserve(indices.size() * 4);
        for (std::size_t i = 0; i < indices.size(); i += 3) {
            const std::uint32_t a = indices[i], b = indices[i + 1], c = indices[i + 2];
            const std::uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
            finer.insert(finer.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
        }
        indices = std::move(finer);
    }
    TriangleMesh mesh;
    mesh.name = "icosphere";
    mesh.indices = std::move(indices);
    mesh.normals = unit;
    mesh.positions.reserve(unit.size());
    for (const Vec3f& p : unit)
        mesh.positions.push_back(center + radius * p);
    return mesh;
}

TriangleMesh make_torus_knot(int segments, int sides, int p, int q, float tube_radius) {
    constexpr float two_pi = 2.0f * std::numbers::pi_v<float>;
    // Centre curve of the knot on a torus of radii 1 and 0.5, and its derivative.
    auto curve = [p, q](float s) {
        const float r = 1.0f + 0.5f * std::cos(static_cast<float>(q) * s);
        return Vec3f(r * std::cos(static_cast<float>(p) * s), r * std::sin(static_cast<float>(p) * s),
                     0.5f * std::sin(static_cast<float>(q) * s));
    };
    TriangleMesh mesh;
    mesh.name = "torus_knot";
    mesh.positions.reserve(static_cast<std::size_t>(segments) * sides);
    mesh.normals.reserve(mesh.positions.capacity());
    for (int i = 0; i < segments; ++i) {
        const float s = two_pi * static_cast<float>(i) / static_cast<float>(segments);
        const Vec3f center = curve(s);
        const Vec3f tangent = normalize(curve(s + 1e-3f) - curve(s - 1e-3f));
        const Vec3f side = normalize(cross(tangent, center));  // a frame that stays away from the tangent
        const Vec3f binormal = cross(side, tangent);
        for (int j = 0; j < sides; ++j) {
            const float angle = two_pi * static_cast<float>(j) / static_cast<float>(sides);
            const Vec3f normal = std::cos(angle) * side + std::sin(angle) * binormal;
            mesh.positions.push_back(center + tube_radius * normal);
            mesh.normals.push_back(normal);
        }
    }
    auto vertex = [segments, sides](int i, int j) {
        return static_cast<std::uint32_t>((i % segments) * sides + (j % sides));
    };
    mesh.indices.reserve(static_cast<std::size_t>(segments) * sides * 6);
    for (int i = 0; i < segments; ++i) {
        for (int j = 0; j < sides; ++j) {
            const std::uint32_t a = vertex(i, j), b = vertex(i + 1, j), c = vertex(i + 1, j + 1),
                                d = vertex(i, j + 1);
            mesh.indices.insert(mesh.indices.end(), {a, b, c, a, c, d});
        }
    }
    return mesh;
}

}  // namespace lancer
