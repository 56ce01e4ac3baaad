// Watertightness end to end (Woop, Benthin & Wald 2013, docs/numerical-contract.md): from a point inside a
// closed mesh every ray hits the mesh, and no later than the surface point it was aimed at. The rays are the
// hostile ones for a triangle test: aimed at the mesh's shared vertices and at points on its shared edges,
// exactly through them where the arithmetic allows (from the exact centre of a mesh whose coordinates then
// subtract exactly). A miss, or a first hit beyond the aimed-at point, is a leak. Every registered structure
// must leak 0 times in watertight mode, Embree in its robust mode 0 times through edges (its cracks at
// vertices are known and counted); the Moller-Trumbore counts are printed beside for information.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string_view>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"

namespace lancer {
namespace {

// 10^6 rays per structure over all the meshes below (brute force a tenth of them, ray_stride); a sanitized
// build (2-5x slower) traces a fifth of them, and leaves out the Moller-Trumbore counts, which are
// information and assert nothing.
#ifdef LANCER_SANITIZED
constexpr std::size_t kRaysPerStructure = 200'000;
constexpr bool kCountMollerTrumbore = false;
#else
constexpr std::size_t kRaysPerStructure = 1'000'000;
constexpr bool kCountMollerTrumbore = true;
#endif

// A closed mesh and a way to pick, for a vertex of it, a point strictly inside the mesh to shoot from.
struct ClosedMesh {
    std::string name;
    TriangleMesh mesh;
    std::function<Vec3f(std::uint32_t vertex, std::mt19937& rng)> inside;
};

// A convex mesh around `center`: half the origins at the centre itself (targets then subtract exactly, so
// the rays pass exactly through vertices), half at random within `radius` of it.
std::function<Vec3f(std::uint32_t, std::mt19937&)> around_center(Vec3f center, float radius) {
    return [center, radius](std::uint32_t, std::mt19937& rng) {
        std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
        if (rng() % 2 == 0) return center;
        Vec3f offset;
        do {
            offset = {unit(rng), unit(rng), unit(rng)};
        } while (length(offset) > 1.0f);
        return center + radius * offset;
    };
}

// The cube [-1, 1]^3, 12 triangles sharing its 8 corners, outward counter-clockwise.
TriangleMesh make_cube() {
    TriangleMesh cube;
    cube.name = "cube";
    for (int i = 0; i < 8; ++i)
        cube.positions.push_back({i & 1 ? 1.0f : -1.0f, i & 2 ? 1.0f : -1.0f, i & 4 ? 1.0f : -1.0f});
    // Corner bits: x = 1, y = 2, z = 4. Each face as a quad (a, b, c, d) counter-clockwise from outside.
    const std::array<std::array<std::uint32_t, 4>, 6> faces = {
        {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}}};
    for (const auto& [a, b, c, d] : faces)
        cube.indices.insert(cube.indices.end(), {a, b, c, a, c, d});
    return cube;
}

std::vector<ClosedMesh> closed_meshes() {
    std::vector<ClosedMesh> meshes;
    meshes.push_back({"icosphere(1)", make_icosphere(1), around_center({0, 0, 0}, 0.5f)});
    meshes.push_back({"icosphere(3)", make_icosphere(3), around_center({0, 0, 0}, 0.5f)});
    meshes.push_back({"cube", make_cube(), around_center({0, 0, 0}, 0.5f)});
    // The knot's tube is not convex as a whole: each ray starts at the centre of the ring of 12 vertices
    // that its target belongs to (make_torus_knot numbers them ring by ring), well inside the tube.
    constexpr int kSides = 12;
    TriangleMesh knot = make_torus_knot(100, kSides);
    std::vector<Vec3f> ring_centers;
    for (std::size_t first = 0; first < knot.positions.size(); first += kSides) {
        Vec3f sum;
        for (int j = 0; j < kSides; ++j)
            sum += knot.positions[first + static_cast<std::size_t>(j)];
        ring_centers.push_back(sum / static_cast<float>(kSides));
    }
    meshes.push_back({"torus knot", std::move(knot), [ring_centers](std::uint32_t vertex, std::mt19937&) {
                          return ring_centers[vertex / kSides];
                      }});
    // 1e6 from the origin: floats 1/16 apart, and every coordinate in [2^19, 2^20), so that differences of
    // coordinates are still exact (Sterbenz) and the rays still pass exactly through the vertices.
    const Vec3f far_center(1e6f, -1e6f, 1e6f);
    meshes.push_back(
        {"icosphere(3) at 1e6", make_icosphere(3, far_center, 50.0f), around_center(far_center, 25.0f)});
    return meshes;
}

// Rays from inside toward the mesh's vertices (a third), random points on its edges (a third) and edge
// midpoints (a third); t = 1 at the target.
std::vector<Ray> rays_toward_vertices_and_edges(const ClosedMesh& closed, std::size_t count,
                                                std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<std::size_t> pick(0, closed.mesh.triangle_count() - 1);
    std::uniform_real_distribution<float> fraction(0.0f, 1.0f);
    std::vector<Ray> rays;
    rays.reserve(count);
    for (std::size_t i = 0; i < count; ++i) {
        const std::size_t triangle = pick(rng);
        const std::uint32_t corner = closed.mesh.indices[3 * triangle + i % 3];
        const std::uint32_t next = closed.mesh.indices[3 * triangle + (i + 1) % 3];
        const Vec3f a = closed.mesh.positions[corner], b = closed.mesh.positions[next];
        const float f = i % 3 == 1 ? fraction(rng) : 0.5f;
        const Vec3f target = i % 3 == 0 ? a : (1.0f - f) * a + f * b;
        const Vec3f origin = closed.inside(corner, rng);
        rays.push_back({origin, target - origin, 0.0f, kInfinity});
    }
    return rays;
}

// Leaks among the rays aimed at vertices (every third ray) and among those aimed at edges.
struct Leaks {
    std::size_t vertex = 0, edge = 0;
};

// The hit must come no later than the aimed-at point, t = 1, give or take the rounding of t (1e-4, a
// thousand ulps) and that of the target: an edge point rounded to the float grid may sit up to half a
// spacing inside the mesh, a few spacings / |direction| before the surface along the ray. A leak goes on to
// the far side of the mesh, t > 1.1 for all of these shapes. Every stride-th ray is traced (copied out only
// when the stride leaves some out).
Leaks count_leaks(const Accel& accel, std::span<const Ray> rays, float grid_spacing, std::size_t stride) {
    std::vector<Ray> strided;
    if (stride > 1) {
        for (std::size_t i = 0; i < rays.size(); i += stride)
            strided.push_back(rays[i]);
    }
    const std::vector<Hit> hits =
        testing::trace_in_parallel(accel, stride > 1 ? std::span<const Ray>(strided) : rays);
    Leaks leaks;
    for (std::size_t j = 0; j < hits.size(); ++j) {
        const std::size_t i = j * stride;
        const float beyond_surface = 1.0f + 1e-4f + 4.0f * grid_spacing / length(rays[i].direction);
        if (hits[j].hit() && hits[j].t <= beyond_surface) continue;
        (i % 3 == 0 ? leaks.vertex : leaks.edge) += 1;
    }
    return leaks;
}

// Brute force runs the scalar kernels that the grid, octree, kd-tree, BVH and Plucker walks run on the same
// rays, but against every triangle, which makes it the test's largest cost (docs/log/ci.md): it traces every
// tenth ray (a stride prime to 3, so a third of them still aim at vertices).
std::size_t ray_stride(std::string_view accel) {
    return accel == "brute" ? 10 : 1;
}

// The distance between adjacent floats at the mesh's largest coordinate.
float grid_spacing(const TriangleMesh& mesh) {
    float largest = 0.0f;
    for (const Vec3f& p : mesh.positions)
        largest = std::max(largest, max_component(abs(p)));
    return std::nextafter(largest, kInfinity) - largest;
}

TEST(Leaks, NoRayEscapesAClosedMeshInWatertightMode) {
    const std::vector<ClosedMesh> meshes = closed_meshes();
    const std::size_t rays_per_mesh = kRaysPerStructure / meshes.size();
    std::vector<std::vector<Triangle>> triangles(meshes.size());
    std::vector<std::vector<Ray>> rays(meshes.size());
    for (std::size_t m = 0; m < meshes.size(); ++m) {
        triangles[m] = meshes[m].mesh.triangles();
        rays[m] =
            rays_toward_vertices_and_edges(meshes[m], rays_per_mesh, 100 + static_cast<std::uint32_t>(m));
    }
    std::printf("%zu rays per structure and triangle test (%zu per mesh, a third at vertices)\n",
                rays_per_mesh * meshes.size(), rays_per_mesh);
    for (std::string_view name : accel_names()) {
        for (std::size_t m = 0; m < meshes.size(); ++m) {
            const Geometry geometry{triangles[m], {}};
            const float spacing = grid_spacing(meshes[m].mesh);
            Leaks leaks[2];
            for (TriangleTest test : {TriangleTest::Watertight, TriangleTest::MollerTrumbore}) {
                if (test == TriangleTest::MollerTrumbore && !kCountMollerTrumbore) continue;
                const std::unique_ptr<Accel> accel = make_accel(name);
                accel->build(geometry, build_options(test));
                leaks[test == TriangleTest::MollerTrumbore] =
                    count_leaks(*accel, rays[m], spacing, ray_stride(name));
            }
            std::printf("%-8s %-20s leaks at vertices / edges: watertight %zu / %zu",
                        std::string(name).c_str(), meshes[m].name.c_str(), leaks[0].vertex, leaks[0].edge);
            if (kCountMollerTrumbore) {
                std::printf(", moller-trumbore %zu / %zu (information)", leaks[1].vertex, leaks[1].edge);
            }
            if (ray_stride(name) != 1) std::printf(", every %zuth ray", ray_stride(name));
            std::printf("\n");
            EXPECT_EQ(leaks[0].edge, 0u) << name << ", " << meshes[m].name << ": rays through edges leak";
            // Embree's robust mode leaves "very tiny cracks at the vertices" (its authors in Embree issues
            // #174 and #188; docs/robustness.md): counted above, not asserted.
            if (!name.starts_with("embree")) {
                EXPECT_EQ(leaks[0].vertex, 0u)
                    << name << ", " << meshes[m].name << ": rays through vertices leak";
            }
        }
    }
}

}  // namespace
}  // namespace lancer
