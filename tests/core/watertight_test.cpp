// The watertight test leaves no gap: rays shot from inside a closed mesh exactly at its shared vertices and
// along its shared edges always hit (Woop, Benthin & Wald 2013). Moller-Trumbore's leaks are counted beside.
#include <gtest/gtest.h>

#include <array>
#include <limits>

#include <random>

#include "accel/brute.hpp"
#include "core/intersect.hpp"
#include "lancer/generate.hpp"

namespace lancer {
namespace {

// A cube [-1, 1]^3 with two triangles per face, outward winding, vertices shared by index.
TriangleMesh make_cube() {
    TriangleMesh mesh;
    for (int i = 0; i < 8; ++i) {
        mesh.positions.push_back({(i & 1) ? 1.0f : -1.0f, (i & 2) ? 1.0f : -1.0f, (i & 4) ? 1.0f : -1.0f});
    }
    mesh.indices = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                    2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    return mesh;
}

// Targets on the surface: every vertex, and points along every edge (midpoints and random fractions).
std::vector<Vec3f> surface_targets(const TriangleMesh& mesh, std::mt19937& rng) {
    std::uniform_real_distribution<float> fraction(0.0f, 1.0f);
    std::vector<Vec3f> targets(mesh.positions.begin(), mesh.positions.end());
    for (std::size_t tri = 0; tri < mesh.triangle_count(); ++tri) {
        for (int corner = 0; corner < 3; ++corner) {
            const Vec3f a = mesh.positions[mesh.indices[3 * tri + corner]];
            const Vec3f b = mesh.positions[mesh.indices[3 * tri + (corner + 1) % 3]];
            targets.push_back(0.5f * (a + b));
            const float f = fraction(rng);
            targets.push_back((1.0f - f) * a + f * b);
        }
    }
    return targets;
}

struct LeakCount {
    std::size_t rays = 0, leaks = 0;
};

LeakCount count_leaks(const TriangleMesh& mesh, const std::vector<Vec3f>& origins, TriangleTest test) {
    std::mt19937 rng(11);
    const std::vector<Vec3f> targets = surface_targets(mesh, rng);
    const std::vector<Triangle> triangles = mesh.triangles();
    BruteAccel brute;
    brute.build({triangles, {}}, build_options(test));
    std::vector<Ray> rays;
    for (const Vec3f& origin : origins) {
        for (const Vec3f& target : targets)
            rays.push_back({origin, target - origin, 0.0f, kInfinity});
    }
    std::vector<std::uint8_t> occluded(rays.size());
    brute.occluded(rays, occluded);
    LeakCount count{rays.size(), 0};
    for (std::uint8_t hit : occluded)
        count.leaks += hit ? 0 : 1;
    return count;
}

const std::vector<Vec3f> kInteriorOrigins = {
    {0, 0, 0}, {0.1f, -0.2f, 0.3f}, {0.5f, 0.5f, 0.5f}, {-0.3f, 0.25f, -0.6f}, {1e-3f, 1e-3f, 0}};

// The axis permutation, exhaustively: kz last, {kx, ky, kz} a permutation of the axes with kx following kz
// cyclically (ky for a negative dominant component: the swap keeps the winding), and RayData choosing it for
// a direction dominant along kz of either sign.
TEST(Watertight, PermutationOfEveryDominantAxisAndSign) {
    for (int kz = 0; kz < 3; ++kz) {
        for (const bool negative : {false, true}) {
            const std::array<int, 3> axes = Watertight::permutation(kz, negative);
            EXPECT_EQ(axes[2], kz);
            EXPECT_EQ(axes[0] + axes[1] + axes[2], 3);
            EXPECT_NE(axes[0], axes[1]);
            EXPECT_EQ(axes[negative ? 1 : 0], (kz + 1) % 3) << kz << " " << negative;
            Vec3f direction(0.25f, -0.5f, 0.125f);
            direction[kz] = negative ? -2.0f : 2.0f;
            const Watertight::RayData data(Ray{{0, 0, 0}, direction, 0.0f, kInfinity});
            EXPECT_EQ(data.kz, kz);
            EXPECT_EQ(data.kx, axes[0]);
            EXPECT_EQ(data.ky, axes[1]);
        }
    }
}

// max_axis, computed without branches, against its rule written as branches (x if x >= y and x >= z, else y
// if y >= z, else z) on every triple of magnitudes from a set with ties, infinities and NaN.
TEST(Watertight, DominantAxisIsTheFirstOfTheLargestComponents) {
    const float values[] = {0.0f, 1.0f, 2.0f, kInfinity, std::numeric_limits<float>::quiet_NaN()};
    for (const float x : values) {
        for (const float y : values) {
            for (const float z : values) {
                int expected = 2;
                if (x >= y && x >= z) {
                    expected = 0;
                } else if (y >= z) {
                    expected = 1;
                }
                EXPECT_EQ(max_axis(Vec3f(x, y, z)), expected) << x << " " << y << " " << z;
            }
        }
    }
}

TEST(Watertight, NoLeakThroughSharedVerticesAndEdgesOfAnIcosphere) {
    const TriangleMesh sphere = make_icosphere(3);
    const LeakCount watertight = count_leaks(sphere, kInteriorOrigins, TriangleTest::Watertight);
    const LeakCount moller = count_leaks(sphere, kInteriorOrigins, TriangleTest::MollerTrumbore);
    std::printf("icosphere: %zu rays at vertices and edges; leaks: watertight %zu, moller-trumbore %zu\n",
                watertight.rays, watertight.leaks, moller.leaks);
    EXPECT_GT(watertight.rays, 40000u);
    EXPECT_EQ(watertight.leaks, 0u);
}

TEST(Watertight, NoLeakThroughTheEdgesAndCornersOfACube) {
    // Axis-aligned faces and edges: rays run exactly along the diagonals that split each face.
    const TriangleMesh cube = make_cube();
    const LeakCount watertight = count_leaks(cube, kInteriorOrigins, TriangleTest::Watertight);
    const LeakCount moller = count_leaks(cube, kInteriorOrigins, TriangleTest::MollerTrumbore);
    std::printf("cube: %zu rays at vertices and edges; leaks: watertight %zu, moller-trumbore %zu\n",
                watertight.rays, watertight.leaks, moller.leaks);
    EXPECT_EQ(watertight.leaks, 0u);
}

// Fuzz finding 22 (docs/robustness.md): a sliver 2^-126 wide, crossed 1 unit from the origin along a
// direction of 2^24, at t = 2^-24. One edge function is exactly zero, another underflowed to -0 in float, and
// the numerator's products fell below 2^-150: the float kernel said t = 0, a hit 1 unit from the sliver that
// brute force reported and the structures whose leaves exclude the origin did not. In double, t = 2^-24.
TEST(Watertight, DenormalEdgeFunctionsKeepTheirHitsT) {
    const Triangle sliver{Vec3f(0x1p-126f), {0x1p-126f, 1, 0}, {0, 0, 0}};
    const Ray ray{{-1, 0, 0}, {0x1p+24f, 0x1.4p-1f, 0x1.02fff8p-128f}, 0, kInfinity};
    TriangleHit hit{};
    ASSERT_TRUE(Watertight::intersect(Watertight::RayData(ray), sliver, ray.tnear, ray.tfar, hit));
    EXPECT_NEAR(hit.t, 0x1p-24f, 0x1p-40f);
    // The fuzzer's interval ends at 2^-126, before the sliver: no hit.
    EXPECT_FALSE(Watertight::intersect(Watertight::RayData(ray), sliver, -0x1.4d4d4cp-50f, 0x1p-126f, hit));
}

// Normal edge functions (a triangle 2^-30 across) whose numerator's products w z (z = 2^-80, the triangle
// just ahead of the origin) fall in the denormal range: the float t erred by up to 2^-10 of itself; the
// numerator below Watertight::kSmallNumerator is computed in double, and t is exact.
TEST(Watertight, ANumeratorInTheDenormalRangeIsComputedInDouble) {
    const float z = 0x1.234568p-80f, size = 0x1.6p-30f;
    const Triangle tiny{{-size, -size, z}, {size, -0x1.3p-31f, z}, {0x1.1p-32f, size, z}};
    const Ray ray{{0, 0, 0}, {0, 0, 1}, 0, kInfinity};
    TriangleHit hit{};
    ASSERT_TRUE(Watertight::intersect(Watertight::RayData(ray), tiny, ray.tnear, ray.tfar, hit));
    EXPECT_EQ(hit.t, z);
    EXPECT_GT(hit.u, 0.0f);
    EXPECT_GT(hit.v, 0.0f);
    EXPECT_LT(hit.u + hit.v, 1.0f);
}

}  // namespace
}  // namespace lancer
