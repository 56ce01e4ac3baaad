// Kernels against analytic cases: slab test, Moller-Trumbore, watertight, sphere, the four ray-plane cases.
#include "core/intersect.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <random>

namespace lancer {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

Ray make_ray(Vec3f origin, Vec3f direction, float tnear = 0.0f, float tfar = kInfinity) {
    return {origin, direction, tnear, tfar};
}

// A right triangle in the z = 0 plane: v0 at the origin, v1 on x, v2 on y.
const Triangle kTriangle{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};

template <class Test>
bool hit_triangle(const Ray& ray, const Triangle& tri, TriangleHit& out) {
    return Test::intersect(typename Test::RayData(ray), tri, ray.tnear, ray.tfar, out);
}

template <class Test>
class TriangleTestSuite : public ::testing::Test {};
using TriangleTests = ::testing::Types<MollerTrumbore, Watertight>;
TYPED_TEST_SUITE(TriangleTestSuite, TriangleTests);

TYPED_TEST(TriangleTestSuite, HitsInteriorWithBarycentricsOfFileOrder) {
    TriangleHit hit;
    ASSERT_TRUE(hit_triangle<TypeParam>(make_ray({0.25f, 0.5f, 2.0f}, {0, 0, -1}), kTriangle, hit));
    EXPECT_FLOAT_EQ(hit.t, 2.0f);
    // p = (1 - u - v) v0 + u v1 + v v2 = (u, v, 0).
    EXPECT_FLOAT_EQ(hit.u, 0.25f);
    EXPECT_FLOAT_EQ(hit.v, 0.5f);
}

TYPED_TEST(TriangleTestSuite, HitsFromBehindAndWithUnnormalisedDirection) {
    TriangleHit hit;
    ASSERT_TRUE(hit_triangle<TypeParam>(make_ray({0.1f, 0.1f, -3.0f}, {0, 0, 2}), kTriangle, hit));
    EXPECT_FLOAT_EQ(hit.t, 1.5f);  // t in multiples of the direction
}

TYPED_TEST(TriangleTestSuite, MissesOutside) {
    TriangleHit hit;
    EXPECT_FALSE(hit_triangle<TypeParam>(make_ray({0.6f, 0.6f, 1.0f}, {0, 0, -1}), kTriangle, hit));
    EXPECT_FALSE(hit_triangle<TypeParam>(make_ray({-0.1f, 0.5f, 1.0f}, {0, 0, -1}), kTriangle, hit));
    EXPECT_FALSE(hit_triangle<TypeParam>(make_ray({0.5f, -0.1f, 1.0f}, {0, 0, -1}), kTriangle, hit));
}

TYPED_TEST(TriangleTestSuite, EdgesAndVerticesAreInside) {
    TriangleHit hit;
    EXPECT_TRUE(
        hit_triangle<TypeParam>(make_ray({0.5f, 0.0f, 1.0f}, {0, 0, -1}), kTriangle, hit));  // edge v0v1
    EXPECT_TRUE(
        hit_triangle<TypeParam>(make_ray({0.0f, 0.5f, 1.0f}, {0, 0, -1}), kTriangle, hit));  // edge v0v2
    EXPECT_TRUE(
        hit_triangle<TypeParam>(make_ray({0.5f, 0.5f, 1.0f}, {0, 0, -1}), kTriangle, hit));  // edge v1v2
    EXPECT_TRUE(
        hit_triangle<TypeParam>(make_ray({1.0f, 0.0f, 1.0f}, {0, 0, -1}), kTriangle, hit));  // vertex v1
}

TYPED_TEST(TriangleTestSuite, GrazingRayInThePlaneMisses) {
    TriangleHit hit;
    EXPECT_FALSE(hit_triangle<TypeParam>(make_ray({-1.0f, 0.25f, 0.0f}, {1, 0, 0}), kTriangle, hit));
    EXPECT_FALSE(hit_triangle<TypeParam>(make_ray({-1.0f, 0.25f, 1e-7f}, {1, 0, 0}), kTriangle, hit));
}

TYPED_TEST(TriangleTestSuite, RespectsTnearAndTfar) {
    TriangleHit hit;
    EXPECT_FALSE(
        hit_triangle<TypeParam>(make_ray({0.2f, 0.2f, 2.0f}, {0, 0, -1}, 0.0f, 1.9f), kTriangle, hit));
    EXPECT_FALSE(
        hit_triangle<TypeParam>(make_ray({0.2f, 0.2f, 2.0f}, {0, 0, -1}, 2.1f, 5.0f), kTriangle, hit));
    EXPECT_TRUE(
        hit_triangle<TypeParam>(make_ray({0.2f, 0.2f, 2.0f}, {0, 0, -1}, 2.0f, 2.0f), kTriangle, hit));
    EXPECT_FALSE(
        hit_triangle<TypeParam>(make_ray({0.2f, 0.2f, -2.0f}, {0, 0, -1}), kTriangle, hit));  // behind
}

TYPED_TEST(TriangleTestSuite, DegenerateTrianglesNeverHit) {
    TriangleHit hit;
    const Triangle collapsed{{0, 0, 0}, {1, 1, 0}, {2, 2, 0}};
    const Triangle point{{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
    EXPECT_FALSE(hit_triangle<TypeParam>(make_ray({1.0f, 1.0f, 2.0f}, {0, 0, -1}), collapsed, hit));
    EXPECT_FALSE(hit_triangle<TypeParam>(make_ray({1.0f, 1.0f, 2.0f}, {0, 0, -1}), point, hit));
}

// Fuzz finding 16: a ray grazing a long sliver (8e-6 rad) near its short edge, 5.7e5 from v0. In float,
// Moller-Trumbore's t was 349.2 for an exact -1.8187151379 (computed in rational arithmetic); the grazing
// band decides it in double. Watertight's t, a convex combination of the vertices' depths, was right.
TEST(TriangleTests, GrazingMollerTrumboreHitIsDecidedInDouble) {
    const Triangle sliver{{-0x1.91919p+18f, -0x1.91919p+18f, -0x1.82be82p+17f},
                          {-0x1p-1f, 0x1.ep-1f, -0x1.ep-1f},
                          {-0x1.ep-1f, 0x1p+0f, 0x1.6p-1f}};
    const Ray ray = make_ray({0x1.ep-1f, -0x1p+0f, -0x1.ep-1f}, {0x1.ep-1f, -0x1.ep-1f, 0}, -8.0f, 8.0f);
    TriangleHit hit;
    ASSERT_TRUE(hit_triangle<MollerTrumbore>(ray, sliver, hit));
    EXPECT_NEAR(hit.t, -1.8187151378988782, 1e-6);
    EXPECT_NEAR(hit.u, 0.9298160010141306, 1e-6);
    EXPECT_NEAR(hit.v, 0.0701834230206884, 1e-6);
    // From t = 1.875, as the fuzzer cast it: no hit.
    EXPECT_FALSE(
        hit_triangle<MollerTrumbore>(make_ray(ray.origin, ray.direction, 1.875f, kInfinity), sliver, hit));
}

// Grazing rays (1e-6 to 1e-1 rad) at triangles of every size from 1 to 1e5, aimed at points inside or near
// them, from up to the triangle's size away. Against the same formula in double (intersect_in_double):
// - hit or miss is always the double test's: the float test decides only where u and v lie farther from the
//   edges than their error bound (fuzz finding 23: before, the two disagreed within 1e-4 of an edge);
// - in the grazing band, the answer is the double test's, bit for bit (the widened float screens never drop
//   a hit it finds);
// - outside it, t errs by at most 2^-24 kappa |T| times a constant, kappa = |d| |e1| |e2| / |det| <= 2^8
//   (max norms). The constant 32 covers the forward error of the cross and dot products (about 24
//   observed).
TEST(TriangleTests, MollerTrumboreDecidesGrazingRaysInDouble) {
    std::mt19937 rng(16);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    auto random_point = [&](float scale) {
        return Vec3f(unit(rng) - 0.5f, unit(rng) - 0.5f, unit(rng) - 0.5f) * scale;
    };
    int float_hits = 0, double_hits = 0, grazing = 0;
    for (int i = 0; i < 20000; ++i) {
        const float size = std::pow(10.0f, 5.0f * unit(rng));
        const Triangle tri{random_point(size), random_point(size), random_point(size)};
        const Vec3f normal = tri.geometric_normal();
        if (!(length(normal) > 0.0f)) continue;
        const float a = 1.2f * unit(rng) - 0.1f, b = (1.2f * unit(rng) - 0.1f) * (1.0f - a);
        const Vec3f target = tri.v0 + a * (tri.v1 - tri.v0) + b * (tri.v2 - tri.v0);
        // A direction in the plane, tilted out of it by the angle.
        const Vec3f in_plane = normalize(cross(normal, random_point(1.0f)));
        const float angle = std::pow(10.0f, -6.0f + 5.0f * unit(rng));
        const Vec3f direction = in_plane + angle * normalize(normal);
        const Vec3f origin = target - (size * unit(rng)) * direction;
        const Ray ray = make_ray(origin, direction, -4.0f * size, 4.0f * size);

        const MollerTrumbore::RayData data(ray);
        TriangleHit reference, hit;
        const bool reference_hit =
            MollerTrumbore::intersect_in_double(data, tri, ray.tnear, ray.tfar, reference);
        const bool float_hit = hit_triangle<MollerTrumbore>(ray, tri, hit);
        const Vec3f e1 = tri.v1 - tri.v0, e2 = tri.v2 - tri.v0;
        const float det = dot(cross(ray.direction, e2), e1);
        const float scales = data.direction_scale * max_component(abs(e1)) * max_component(abs(e2));
        if (!(std::fabs(det) > MollerTrumbore::kIllConditioned * scales)) continue;  // the miss band
        ASSERT_EQ(float_hit, reference_hit) << "ray " << i;
        if (std::fabs(det) <= MollerTrumbore::kGrazingBand * scales) {
            ++grazing;
            if (!float_hit) continue;
            ++double_hits;
            ASSERT_TRUE(std::memcmp(&hit, &reference, sizeof(TriangleHit)) == 0) << "ray " << i;
            continue;
        }
        if (!float_hit) continue;
        ++float_hits;
        const double kappa = scales / std::fabs(det);
        const double bound = 32.0 * 0x1p-24 * kappa * max_component(abs(ray.origin - tri.v0));
        ASSERT_LE(std::fabs(double(hit.t) - double(reference.t)) * data.direction_scale, bound)
            << "ray " << i;
    }
    // Both paths were exercised, on hits as on misses.
    EXPECT_GT(grazing, 5000);
    EXPECT_GT(double_hits, 2000);
    EXPECT_GT(float_hits, 2000);
}

// Fuzz finding 23: rays aimed just outside an edge or a vertex, from 1/16 to 8 scene sizes away (the
// origins a structure sees after ray conditioning), at triangles across the unit cube, one in three a sliver.
// The float Moller-Trumbore reported about one such ray in twenty as a hit, up to 75 2^-24 |T| from the exact
// line, beyond the geometric tolerance by which the structures grow their boxes. Within its error bound of an
// edge the double test decides now: outside the ill-conditioned band, hit or miss is the double test's on
// every ray.
TEST(TriangleTests, MollerTrumboreDecidesRaysNearAnEdgeInDouble) {
    std::mt19937 rng(23);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    auto random_point = [&] { return Vec3f(unit(rng), unit(rng), unit(rng)); };
    int hits = 0, misses = 0;
    for (int i = 0; i < 40000; ++i) {
        Triangle tri{random_point(), random_point(), random_point()};
        if (i % 3 == 0) tri.v2 = tri.v0 + 0.5f * (tri.v1 - tri.v0) + 0.01f * random_point();
        const std::array<Vec3f, 3> vertices = {tri.v0, tri.v1, tri.v2};
        const auto edge = static_cast<std::size_t>(i % 3);
        const Vec3f from = vertices[edge], to = vertices[(edge + 1) % 3];
        const float along =
            i % 4 == 0 ? 0.0f : (unit(rng) + 1.0f) / 2.0f;  // a vertex, or a point of the edge
        const float distance = std::ldexp(8.0f, -static_cast<int>(8.0f * (unit(rng) + 1.0f) / 2.0f));
        const Vec3f target = from + along * (to - from) +
                             (0x1p-24f * 64.0f * distance * unit(rng)) * normalize(random_point());
        const Vec3f origin = target + distance * normalize(random_point());
        const Ray ray = make_ray(origin, target - origin, -kInfinity, kInfinity);
        const MollerTrumbore::RayData data(ray);
        const Vec3f e1 = tri.v1 - tri.v0, e2 = tri.v2 - tri.v0;
        const float scales = data.direction_scale * max_component(abs(e1)) * max_component(abs(e2));
        if (!(std::fabs(dot(cross(ray.direction, e2), e1)) > MollerTrumbore::kIllConditioned * scales))
            continue;  // the miss band
        TriangleHit reference, hit;
        const bool reference_hit =
            MollerTrumbore::intersect_in_double(data, tri, ray.tnear, ray.tfar, reference);
        ASSERT_EQ(hit_triangle<MollerTrumbore>(ray, tri, hit), reference_hit) << "ray " << i;
        ++(reference_hit ? hits : misses);
    }
    // Aimed at the edges: both answers are common.
    EXPECT_GT(hits, 10000);
    EXPECT_GT(misses, 10000);
}

TEST(TriangleTests, WatertightAgreesWithMollerTrumboreOnRandomRays) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
    auto random_point = [&] { return Vec3f(coordinate(rng), coordinate(rng), coordinate(rng)); };
    int both = 0;
    for (int i = 0; i < 40000; ++i) {
        const Triangle tri{random_point(), random_point(), random_point()};
        // Aim at a random point of the triangle's plane near it, so that most rays hit.
        const float a = coordinate(rng), b = coordinate(rng);
        const Vec3f target = tri.v0 + a * (tri.v1 - tri.v0) + b * (tri.v2 - tri.v0);
        const Vec3f origin = random_point() * 3.0f;
        const Ray ray = make_ray(origin, target - origin);
        // Well-conditioned cases only: slivers and grazing rays amplify rounding differently in each test.
        const Vec3f normal = tri.geometric_normal();
        if (length(normal) < 0.1f || std::fabs(dot(normalize(normal), normalize(ray.direction))) < 0.2f)
            continue;
        TriangleHit mt, wt;
        const bool mt_hit = hit_triangle<MollerTrumbore>(ray, tri, mt);
        const bool wt_hit = hit_triangle<Watertight>(ray, tri, wt);
        // Near an edge the two tests may disagree by rounding; away from it they must agree exactly on
        // hit/miss.
        const float margin = 1e-4f;
        const bool near_edge =
            mt_hit ? (mt.u < margin || mt.v < margin || 1.0f - mt.u - mt.v < margin)
                   : (wt_hit && (wt.u < margin || wt.v < margin || 1.0f - wt.u - wt.v < margin));
        if (near_edge) continue;
        ASSERT_EQ(mt_hit, wt_hit) << "ray " << i;
        if (!mt_hit) continue;
        ++both;
        EXPECT_NEAR(mt.t, wt.t, 1e-4f * std::max(1.0f, std::fabs(mt.t)));
        EXPECT_NEAR(mt.u, wt.u, 1e-4f);
        EXPECT_NEAR(mt.v, wt.v, 1e-4f);
    }
    EXPECT_GT(both, 3000);  // the comparison covered many hits
}

TEST(SphereTests, HitsFromOutsideAtTheNearRoot) {
    TriangleHit hit;
    const Sphere sphere{{0, 0, 0}, 1.0f, 0};
    ASSERT_TRUE(intersect_sphere(make_ray({0, 0, 5}, {0, 0, -1}), sphere, 0.0f, kInfinity, hit));
    EXPECT_FLOAT_EQ(hit.t, 4.0f);
    EXPECT_NEAR(hit.v, 0.0f, 1e-6f);  // the north pole: polar angle 0
}

TEST(SphereTests, HitsFromInsideAtTheFarRoot) {
    TriangleHit hit;
    const Sphere sphere{{1, 2, 3}, 2.0f, 0};
    ASSERT_TRUE(intersect_sphere(make_ray({1, 2, 3}, {0, 0.5f, 0}), sphere, 0.0f, kInfinity, hit));
    EXPECT_FLOAT_EQ(hit.t, 4.0f);
}

TEST(SphereTests, MissesBesideBehindAndBeyondTfar) {
    TriangleHit hit;
    const Sphere sphere{{0, 0, 0}, 1.0f, 0};
    EXPECT_FALSE(intersect_sphere(make_ray({0, 1.001f, 5}, {0, 0, -1}), sphere, 0.0f, kInfinity, hit));
    EXPECT_FALSE(intersect_sphere(make_ray({0, 0, 5}, {0, 0, 1}), sphere, 0.0f, kInfinity, hit));
    EXPECT_FALSE(intersect_sphere(make_ray({0, 0, 5}, {0, 0, -1}), sphere, 0.0f, 3.9f, hit));
}

TEST(SphereTests, ZeroAndNaNRadiusNeverHit) {
    TriangleHit hit;
    EXPECT_FALSE(
        intersect_sphere(make_ray({0, 0, 5}, {0, 0, -1}), {{0, 0, 0}, 0.0f, 0}, 0.0f, kInfinity, hit));
    EXPECT_FALSE(
        intersect_sphere(make_ray({0, 0, 5}, {0, 0, -1}), {{0, 0, 0}, kNaN, 0}, 0.0f, kInfinity, hit));
}

TEST(SphereTests, StaysAccurateFarFromASmallSphere) {
    // The textbook discriminant b^2 - 4ac cancels catastrophically here; Haines et al.'s form does not.
    TriangleHit hit;
    const Sphere sphere{{0, 0, 0}, 0.01f, 0};
    ASSERT_TRUE(intersect_sphere(make_ray({0.005f, 0, 1e4f}, {0, 0, -1}), sphere, 0.0f, kInfinity, hit));
    const float expected = 1e4f - std::sqrt(0.01f * 0.01f - 0.005f * 0.005f);
    EXPECT_NEAR(hit.t, expected, 1e-3f);
}

// Fuzz finding 17: radius 3e-41 and a ray 1.4e-30 from the centre, whose float squares both underflow to 0.
// In double: a miss; a ray through the centre hits at the radius, whose square is no longer 0.
TEST(SphereTests, TinySphereSquaresDoNotUnderflow) {
    const Sphere tiny{{0, 0, 0}, 0x1.81p-135f, 0};
    TriangleHit hit;
    EXPECT_FALSE(
        intersect_sphere(make_ray(Vec3f(0x1.4484cp-100f), {0x1.4484cp-100f, 0x1.4484cp-100f, 0.9375f}, -1, 1),
                         tiny, -1.0f, 1.0f, hit));
    ASSERT_TRUE(intersect_sphere(make_ray({0, 0, 1}, {0, 0, -1}), tiny, 0.0f, kInfinity, hit));
    EXPECT_EQ(hit.t, 1.0f);  // 1 - 3e-41 rounds to 1
}

TEST(PlaneTests, TheFourCasesOfSeed004) {
    const Plane ground{{0, 1, 0}, 2.0f, 0};  // y = 2
    float t = 0.0f;
    EXPECT_EQ(classify_plane(make_ray({0, 0, 0}, {1, 0, 0}), ground, 0.0f, t), PlaneCase::Parallel);
    EXPECT_EQ(classify_plane(make_ray({0, 2, 0}, {1, 0, 0}), ground, 0.0f, t), PlaneCase::InPlane);
    EXPECT_EQ(classify_plane(make_ray({0, 0, 0}, {0, -1, 0}), ground, 0.0f, t), PlaneCase::Behind);
    EXPECT_FLOAT_EQ(t, -2.0f);
    EXPECT_EQ(classify_plane(make_ray({0, 0, 0}, {0, 1, 1}), ground, 0.0f, t), PlaneCase::Ahead);
    EXPECT_FLOAT_EQ(t, 2.0f);
    EXPECT_TRUE(intersect_plane(make_ray({0, 0, 0}, {0, 1, 1}), ground, 0.0f, kInfinity, t));
    EXPECT_FALSE(intersect_plane(make_ray({0, 0, 0}, {0, 1, 1}), ground, 0.0f, 1.5f, t));
    EXPECT_FALSE(intersect_plane(make_ray({0, 2, 0}, {1, 0, 0}), ground, 0.0f, kInfinity, t));
}

TEST(SlabTests, HitMissAndInside) {
    const Box3f box{{-1, -1, -1}, {1, 1, 1}};
    float entry = 0.0f, exit = 0.0f;
    EXPECT_TRUE(intersect_box(SlabRay(make_ray({0, 0, 5}, {0, 0, -1})), box, 0.0f, kInfinity, entry, exit));
    EXPECT_FLOAT_EQ(entry, 4.0f);
    EXPECT_NEAR(exit, 6.0f, 1e-5f);
    EXPECT_FALSE(intersect_box(SlabRay(make_ray({0, 2, 5}, {0, 0, -1})), box, 0.0f, kInfinity, entry, exit));
    EXPECT_TRUE(
        intersect_box(SlabRay(make_ray({0.5f, 0.5f, 0.5f}, {1, 1, 0})), box, 0.0f, kInfinity, entry, exit));
    EXPECT_FLOAT_EQ(entry, 0.0f);  // origin inside: the interval starts at tnear
    EXPECT_FALSE(intersect_box(SlabRay(make_ray({0, 0, 5}, {0, 0, -1})), box, 0.0f, 3.0f, entry, exit));
}

TEST(SlabTests, ZeroDirectionComponentsAndRaysInAFacePlane) {
    const Box3f box{{-1, -1, -1}, {1, 1, 1}};
    float entry = 0.0f, exit = 0.0f;
    // Axis-parallel, beside the box in x: the x slab is empty.
    EXPECT_FALSE(intersect_box(SlabRay(make_ray({2, 0, 5}, {0, 0, -1})), box, 0.0f, kInfinity, entry, exit));
    // Running exactly in the plane x = 1 of a face: 0 * inf = NaN must not lose the box.
    EXPECT_TRUE(intersect_box(SlabRay(make_ray({1, 0, 5}, {0, 0, -1})), box, 0.0f, kInfinity, entry, exit));
    EXPECT_FLOAT_EQ(entry, 4.0f);
    // Along an edge (x = 1 and y = 1).
    EXPECT_TRUE(intersect_box(SlabRay(make_ray({1, 1, 5}, {0, 0, -1})), box, 0.0f, kInfinity, entry, exit));
}

TEST(RayTests, ValidityContract) {
    EXPECT_TRUE(is_valid(make_ray({0, 0, 0}, {0, 0, 1})));
    EXPECT_TRUE(is_valid(make_ray({0, 0, 0}, {0, 0, 1}, 1.0f, 1.0f)));
    EXPECT_FALSE(is_valid(make_ray({0, 0, 0}, {0, 0, 0})));
    EXPECT_FALSE(is_valid(make_ray({kNaN, 0, 0}, {0, 0, 1})));
    EXPECT_FALSE(is_valid(make_ray({0, 0, 0}, {0, kInfinity, 1})));
    EXPECT_FALSE(is_valid(make_ray({0, 0, 0}, {0, 0, 1}, 2.0f, 1.0f)));
    EXPECT_FALSE(is_valid(make_ray({0, 0, 0}, {0, 0, 1}, kNaN, 1.0f)));
    EXPECT_FALSE(is_valid(make_ray({0, 0, 0}, {0, 0, 1}, 0.0f, kNaN)));
    EXPECT_FALSE(is_valid(make_ray({0, 0, 0}, {0, 0, 1}, -kInfinity, 1.0f)));
}

// is_valid and is_finite test by comparisons (constexpr, so that the GPU kernels call them too): they must
// answer as the contract written with <cmath>, each field in turn over the special values.
TEST(RayTests, ValidityIsTheContractFieldByField) {
    static_assert(is_valid(Ray{{0, 0, 0}, {1, 0, 0}, 0.0f, kInfinity}) && !is_valid(Ray{}));
    const auto finite = [](const Vec3f& v) {
        return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
    };
    const float values[] = {0.0f, -0.0f, 1.5f, -2.0f, 0x1p-149f, 3.4028235e38f, kInfinity, -kInfinity, kNaN};
    for (const float a : values) {
        EXPECT_EQ(is_finite_number(a), std::isfinite(a)) << a;
        const Ray base{{0, 0, 0}, {1, 0, 0}, 0.0f, kInfinity};
        Ray rays[5] = {base, base, base, base, base};
        rays[0].origin.y = a;
        rays[1].direction.z = a;
        rays[2].direction = {a, 0.0f, 0.0f};
        rays[3].tnear = a;
        rays[4].tfar = a;
        for (const Ray& ray : rays) {
            EXPECT_EQ(is_finite(ray.origin), finite(ray.origin)) << a;
            const bool contract =
                finite(ray.origin) && finite(ray.direction) &&
                (ray.direction.x != 0.0f || ray.direction.y != 0.0f || ray.direction.z != 0.0f) &&
                std::isfinite(ray.tnear) && !std::isnan(ray.tfar) && ray.tnear <= ray.tfar;
            EXPECT_EQ(is_valid(ray), contract) << a;
        }
    }
}

TEST(RayTests, ClosestOrderBreaksTiesByIndex) {
    const Hit best{2.0f, 5, 0.0f, 0.0f};
    EXPECT_TRUE(closer(1.0f, 9, best));
    EXPECT_TRUE(closer(2.0f, 4, best));
    EXPECT_FALSE(closer(2.0f, 6, best));
    EXPECT_FALSE(closer(3.0f, 0, best));
}

}  // namespace
}  // namespace lancer
