#include "lancer/generate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <unordered_map>
#include <utility>

namespace lancer {

TriangleMesh subdivided(const TriangleMesh& mesh) {
    TriangleMesh finer;
    finer.name = mesh.name;
    finer.material = mesh.material;
    finer.positions = mesh.positions;
    finer.normals = mesh.normals;
    const std::size_t triangles = mesh.triangle_count();
    std::unordered_map<std::uint64_t, std::uint32_t> midpoints;
    midpoints.reserve(triangles * 3 / 2 + 3);
    const auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
        const auto [low, high] = std::minmax(a, b);
        const std::uint64_t key = (static_cast<std::uint64_t>(low) << 32) | high;
        const auto [it, inserted] =
            midpoints.try_emplace(key, static_cast<std::uint32_t>(finer.positions.size()));
        if (inserted) {
            finer.positions.push_back(0.5f * (mesh.positions[a] + mesh.positions[b]));
            if (!mesh.normals.empty()) finer.normals.push_back(normalize(mesh.normals[a] + mesh.normals[b]));
        }
        return it->second;
    };
    finer.indices.reserve(mesh.indices.size() * 4);
    for (std::size_t i = 0; i < mesh.indices.size(); i += 3) {
        const std::uint32_t a = mesh.indices[i], b = mesh.indices[i + 1], c = mesh.indices[i + 2];
        const std::uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
        finer.indices.insert(finer.indices.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    finer.material_ids.reserve(mesh.material_ids.size() * 4);
    for (const std::uint32_t id : mesh.material_ids)
        finer.material_ids.insert(finer.material_ids.end(), {id, id, id, id});
    return finer;
}

TriangleMesh make_icosphere(int subdivisions, Vec3f center, float radius) {
    // The 12 vertices of an icosahedron: cyclic permutations of (0, +-1, +-phi).
    const float phi = (1.0f + std::sqrt(5.0f)) / 2.0f;
    TriangleMesh unit;
    unit.name = "icosphere";
    unit.positions = {{-1, phi, 0},  {1, phi, 0},  {-1, -phi, 0}, {1, -phi, 0}, {0, -1, phi},  {0, 1, phi},
                      {0, -1, -phi}, {0, 1, -phi}, {phi, 0, -1},  {phi, 0, 1},  {-phi, 0, -1}, {-phi, 0, 1}};
    for (Vec3f& p : unit.positions)
        p = normalize(p);
    unit.indices = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                    4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                    6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
    for (int level = 0; level < subdivisions; ++level) {
        // Each new midpoint projected back on the sphere: normalize((a + b) / 2) is normalize(a + b) bit for
        // bit, the halving being exact.
        const std::size_t coarse = unit.positions.size();
        unit = subdivided(unit);
        for (std::size_t v = coarse; v < unit.positions.size(); ++v)
            unit.positions[v] = normalize(unit.positions[v]);
    }
    TriangleMesh mesh;
    mesh.name = "icosphere";
    mesh.indices = std::move(unit.indices);
    mesh.normals = unit.positions;
    mesh.positions.reserve(unit.positions.size());
    for (const Vec3f& p : unit.positions)
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

std::vector<Transform> random_placements(const Box3f& bounds, int count) {
    std::mt19937 rng(2026);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), scale(0.5f, 1.5f), angle(0.0f, 6.2831853f);
    const float size = max_component(bounds.extent());
    const float side = 0.9f * size * std::cbrt(static_cast<float>(count));
    const Transform to_origin = Transform::translation(-1.0f * bounds.center());
    std::vector<Transform> placements;
    placements.reserve(static_cast<std::size_t>(count));
    for (int i = 0; i < count; ++i) {
        // One draw per statement: the order of a call's arguments and of an operator's operands is
        // unspecified, and compilers differ. This is the order GCC gave the scenes measured in docs/.
        const float axis_z = unit(rng) + 0.01f;
        const float axis_y = unit(rng);
        const float axis_x = unit(rng);
        const float s = scale(rng);
        const float turn = angle(rng);
        const float x = side * unit(rng);
        const float y = side * unit(rng);
        const float z = side * unit(rng);
        placements.push_back(Transform::translation({x, y, z}) *
                             Transform::rotation({axis_x, axis_y, axis_z}, turn) *
                             Transform::scaling(Vec3f(s)) * to_origin);
    }
    return placements;
}

}  // namespace lancer
