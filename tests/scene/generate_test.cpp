// Generated meshes are closed (every edge shared by exactly two triangles, in opposite directions) and
// wound outward, which the watertightness and renderer tests rely on.
#include "lancer/generate.hpp"

#include <gtest/gtest.h>

#include <map>

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

}  // namespace
}  // namespace lancer
