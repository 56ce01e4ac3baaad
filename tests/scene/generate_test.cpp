// Generated meshes are closed (every edge shared by exactly two triangles, in opposite directions) and
// wound outward, which the watertightness and renderer tests rely on.
#include "lancer/generate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>

namespace lancer {
namespace {

void expect_closed(const TriangleMesh& mesh) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed_edges;
    for (std::size_t tri = 0; tri < mesh.triangle_count(); ++tri) {
        for (int corner = 0; corner < 3; ++corner) {
            ++directed_edges[{mesh.indices[3 * tri + corner], mesh.indices[3 * tri + (corner + 1) % 3]}];
        }
    }
    for (const auto& [edge, count] : directed_edges) {
        ASSERT_EQ(count, 1) << "edge used twice in the same direction";
        ASSERT_EQ(directed_edges.count({edge.second, edge.first}), 1u) << "open edge";
    }
}

// Positive for a closed mesh wound outward around `inside`.
double signed_volume(const TriangleMesh& mesh, Vec3f inside) {
    double volume = 0.0;
    for (std::size_t tri = 0; tri < mesh.triangle_count(); ++tri) {
        const Triangle t = mesh.triangle(tri);
        volume += dot(t.v0 - inside, cross(t.v1 - inside, t.v2 - inside)) / 6.0;
    }
    return volume;
}

TEST(Generate, IcosphereIsClosedOutwardAndOnTheSphere) {
    const TriangleMesh mesh = make_icosphere(2, {1, 2, 3}, 2.0f);
    EXPECT_EQ(mesh.triangle_count(), 20u * 16u);
    EXPECT_EQ(mesh.normals.size(), mesh.positions.size());
    for (const Vec3f& p : mesh.positions)
        EXPECT_NEAR(length(p - Vec3f(1, 2, 3)), 2.0f, 1e-5f);
    expect_closed(mesh);
    EXPECT_GT(signed_volume(mesh, {1, 2, 3}), 0.0);
}

TEST(Generate, TorusKnotIsAClosedTube) {
    const TriangleMesh mesh = make_torus_knot(200, 8);
    EXPECT_EQ(mesh.triangle_count(), 2u * 200u * 8u);
    expect_closed(mesh);
    // The tube winds outward: its signed volume about the knot is pi r^2 L > 0 (origin-independent).
    EXPECT_GT(signed_volume(mesh, {0, 0, 0}), 0.0);
}

// Subdivision keeps the shape: a closed mesh stays closed and wound the same way, with the same volume (the
// midpoints lie on the faces), four times the triangles, one new vertex per edge, each triangle's material on
// its four, unit normals; the corners of the coarse mesh keep their indices.
TEST(Generate, SubdivisionSplitsEachTriangleInFourAndKeepsTheShape) {
    TriangleMesh mesh = make_torus_knot(40, 6);
    mesh.material_ids.resize(mesh.triangle_count());
    for (std::size_t tri = 0; tri < mesh.triangle_count(); ++tri)
        mesh.material_ids[tri] = static_cast<std::uint32_t>(tri % 5);
    const TriangleMesh finer = subdivided(mesh);
    EXPECT_EQ(finer.triangle_count(), 4 * mesh.triangle_count());
    // A closed mesh of T triangles has 3T / 2 edges.
    EXPECT_EQ(finer.positions.size(), mesh.positions.size() + 3 * mesh.triangle_count() / 2);
    EXPECT_EQ(finer.normals.size(), finer.positions.size());
    for (std::size_t v = 0; v < mesh.positions.size(); ++v)
        EXPECT_EQ(finer.positions[v], mesh.positions[v]);
    for (const Vec3f& normal : finer.normals)
        EXPECT_NEAR(length(normal), 1.0f, 1e-6f);
    ASSERT_EQ(finer.material_ids.size(), finer.triangle_count());
    for (std::size_t tri = 0; tri < finer.triangle_count(); ++tri)
        EXPECT_EQ(finer.material_ids[tri], mesh.material_ids[tri / 4]) << tri;
    expect_closed(finer);
    const double coarse_volume = signed_volume(mesh, {0, 0, 0});
    EXPECT_NEAR(signed_volume(finer, {0, 0, 0}), coarse_volume, 1e-5 * coarse_volume);
    EXPECT_GT(coarse_volume, 0.0);
    // Twice: 16 times the triangles, still closed.
    const TriangleMesh finest = subdivided(finer);
    EXPECT_EQ(finest.triangle_count(), 16 * mesh.triangle_count());
    expect_closed(finest);
}

// The placements follow the draw order their header states, which no call's unspecified argument order may
// change (clang and GCC evaluate arguments in opposite orders): the bench's instanced scene is the same
// under every compiler. The recipe is replayed here from its statement in lancer/generate.hpp.
TEST(Generate, RandomPlacementsDrawInTheStatedOrder) {
    const Box3f bounds{{-1.0f, -2.0f, -3.0f}, {3.0f, 2.0f, 1.0f}};
    constexpr int kCount = 27;
    const std::vector<Transform> placements = random_placements(bounds, kCount);
    ASSERT_EQ(placements.size(), static_cast<std::size_t>(kCount));
    std::mt19937 rng(2026);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), scale(0.5f, 1.5f), angle(0.0f, 6.2831853f);
    const float side = 0.9f * max_component(bounds.extent()) * std::cbrt(static_cast<float>(kCount));
    for (int i = 0; i < kCount; ++i) {
        Vec3f axis, position;
        axis.z = unit(rng) + 0.01f;
        axis.y = unit(rng);
        axis.x = unit(rng);
        const float s = scale(rng);
        const float turn = angle(rng);
        position.x = side * unit(rng);
        position.y = side * unit(rng);
        position.z = side * unit(rng);
        const Transform expected = Transform::translation(position) * Transform::rotation(axis, turn) *
                                   Transform::scaling(Vec3f(s)) *
                                   Transform::translation(-1.0f * bounds.center());
        for (int row = 0; row < 3; ++row) {
            for (int column = 0; column < 4; ++column)
                EXPECT_EQ(placements[i].m[row][column], expected.m[row][column])
                    << "placement " << i << ", row " << row << ", column " << column;
        }
    }
}

}  // namespace
}  // namespace lancer
