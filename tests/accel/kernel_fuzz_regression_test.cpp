// The fuzz findings in the triangle and sphere tests' arithmetic, replayed in the normal suite
// (docs/robustness.md, "Findings and fixes"; docs/numerical-contract.md, "Triangle tests" and "Spheres"):
// every structure agrees with brute force on them, and brute force gives exact arithmetic's answer.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "fuzz_regression.hpp"
#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using fuzz_regression::expect_every_structure_agrees;
using fuzz_regression::trace;
using testing::TestScene;

// Fuzz finding 13 (docs/robustness.md): a ray starting on the scene's upper y face with a direction near the
// float range. Moller-Trumbore's det = (d x e2) . e1 overflowed to +inf, inv_det was 0 and u = v = t = 0
// passed every test: a hit at t = -0 on triangle 4, which the ray passes 2 units away from (u = -0.67,
// v = -0.74 in double). Brute force and the structures that test that triangle reported it; the BVH, whose
// leaf box excludes the triangle, did not. The scene's triangles, and rays with a huge component.
TestScene huge_direction_scene() {
    return {"huge direction",
            {{{-0x1.3cp+2f, 2, 0x1.7p+1f}, {-0x1.12fcfcp-124f, -0x1.be002p+7f, -4}, {-4, 1, 1}},
             {{-5, -5, -0x1.3cp+2f}, {-0x1.ep-1f, -0x1.ep-1f, 1}, {-1, -1, 1}},
             {{-1, -0x1.ep-1f, 0x1.ep-1f}, {-1, -1, 1}, {-0x1.ep-1f, -0x1.ep-1f, 1}},
             {Vec3f(-5), {-5, -0x1.6p+0f, 0x1.dp+0f}, {0x1.9p+0f, 0x1.1p+0f, 0x1.cp+0f}},
             {{0x1.3p+0f, 0x1.5p+0f, 0x1.1p+1f},
              {0x1.ep+0f, 0.3125f, 0.1875f},
              {0x1.b8p+1f, 0x1.7p+1f, 0x1.7p+1f}},
             {Vec3f(0x1.7p+1f), Vec3f(0x1.7p+1f), {-0x1.58p+1f, 0x1.7p+1f, -5}},
             {{-0x1.3p+2f, 0x1.7p+1f, 0x1.7p+1f}, Vec3f(0x1.7p+1f), {-0x1.48p+1f, 0x1.7p+1f, 0x1.7p+1f}},
             {Vec3f(0x1.7p+1f), Vec3f(0x1.7p+1f), Vec3f(0)}},
            {}};
}

TEST(FuzzRegression, SurfaceHitWithAHugeDirection) {
    const TestScene scene = huge_direction_scene();
    const Vec3f origin(-0x1.ep-1f, 0x1.7p+1f, 0x1.7p+1f);
    // The fuzzer's ray (d.y = 8.4e37), the same downwards, and rays whose x component is 1e36 or 1e37,
    // which also reported false hits at t = -0 (on triangle 0) before the fix.
    std::vector<Ray> rays;
    for (const float sign : {1.0f, -1.0f}) {
        rays.push_back({origin, {0x1.7p+1f, sign * 0x1.fc05fep+125f, 1}, 0, 0.5f});
        for (const float huge : {1e36f, 1e37f})
            rays.push_back({origin, {sign * huge, 0x1.7p+1f, 1}, 0, 0.5f});
    }
    // The fuzzer's rays pass 2 units from every triangle (the x rays graze triangle 4's vertex 2).
    for (const std::vector<Hit>& expected : expect_every_structure_agrees(scene, rays))
        EXPECT_FALSE(expected[0].hit() || expected[3].hit());
}

// The other side of finding 13: a direction scaled by a power of two is the same ray, and finds the same
// primitive at t scaled back exactly. At 2^120 the largest component of ray 0 passes 2^126 (its reciprocal,
// which the box tests use, is denormal). Before the fix Moller-Trumbore's det overflowed at 2^120 and it
// missed triangles that the unscaled rays hit.
TEST(FuzzRegression, AHugeDirectionFindsWhatItsUnscaledCopyFinds) {
    const TestScene scene = huge_direction_scene();
    const Vec3f origin(7, 6.5f, -8);
    std::vector<Ray> unscaled;
    for (const Triangle& triangle : scene.triangles) {
        const Vec3f centroid = (triangle.v0 + triangle.v1 + triangle.v2) * (1.0f / 3.0f);
        unscaled.push_back({origin, centroid - origin, 0, kInfinity});
    }
    for (const TriangleTest test : {TriangleTest::MollerTrumbore}) {
        for (const std::string_view name : accel_names()) {
            if (name.starts_with("embree")) continue;
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(scene.geometry(), build_options(test));
            const std::vector<Hit> expected = trace(*accel, unscaled);
            for (const int exponent : {-100, 100, 120}) {
                std::vector<Ray> scaled = unscaled;
                for (Ray& ray : scaled)
                    ray.direction = ray.direction * std::ldexp(1.0f, exponent);
                const std::vector<Hit> hits = trace(*accel, scaled);
                for (std::size_t i = 0; i < hits.size(); ++i) {
                    const std::string context =
                        std::string(name) + ", 2^" + std::to_string(exponent) + ", ray " + std::to_string(i);
                    ASSERT_EQ(hits[i].prim, expected[i].prim) << context;
                    if (expected[i].hit()) {
                        EXPECT_EQ(hits[i].t, std::ldexp(expected[i].t, -exponent)) << context;
                    }
                }
            }
        }
    }
}

// Finding 16 (docs/robustness.md): a ray that grazes a long sliver (triangle 4, from -4e5 to within a unit
// of the origin) at 8e-6 rad, near its short edge. Its exact line meets the triangle at t = -1.819, outside
// [1.875, inf]; Moller-Trumbore in float said t = 349.2 (an error of |T| / 1600 where T = o - v0), so brute
// force answered a hit 330 units outside the scene box that no structure visits. Grazing hits are now
// decided in double (MollerTrumbore::intersect_in_double): every structure and brute force miss.
TEST(FuzzRegression, GrazingSliverHitIsDecidedInDouble) {
    const TestScene scene{
        "grazing sliver",
        {{{-0x1.ep-1f, -0x1.ep-1f, 0x1p+0f},
          {-0x1.4p+2f, -0x1.ep-1f, 0x1.ep-1f},
          {-0x1p+0f, -0x1.cp-1f, 0x1.cp-1f}},
         {{-0x1.ep-1f, -0x1.ep-1f, 0x1.cp-1f},
          {-0x1.ep-1f, -0x1.cp-1f, 0x1.ep-1f},
          {-0x1.ep-1f, -0x1.ep-1f, 0x1.cp-1f}},
         {{-0x1p+0f, -0x1.cp-1f, 0x1.cp-1f}, Vec3f(0x1.6p-1f), Vec3f(0x1.6p-1f)},
         {Vec3f(0x1.6p-1f), {0x1.6p-1f, 0x1.6p-1f, 0x1.ep-1f}, {-0x1.ap-1f, -0x1.4p+2f, -0x1.91919p+18f}},
         {{-0x1.91919p+18f, -0x1.91919p+18f, -0x1.82be82p+17f},
          {-0x1p-1f, 0x1.ep-1f, -0x1.ep-1f},
          {-0x1.ep-1f, 0x1p+0f, 0x1.6p-1f}},
         {{0x1.6p-1f, -0x1.ep-1f, -0x1.ep-1f},
          {0x1.cp-1f, -0x1.ep-1f, -0x1.cp-1f},
          {0x1.ep-1f, -0x1p+0f, -0x1.ep-1f}}},
        {{{-0x1p+0f, -0x1.cp-1f, 0x1.cp-1f}, 0x1p+0f, 0},
         {{-0x1.ep-1f, 0x1.ep-1f, -0x1.ep-1f}, 0x1.cp-1f, 0}}};
    const Ray grazing{{0x1.ep-1f, -0x1p+0f, -0x1.ep-1f}, {0x1.ep-1f, -0x1.ep-1f, 0}, 0x1.ep+0f, kInfinity};
    for (const std::vector<Hit>& expected : expect_every_structure_agrees(scene, std::span(&grazing, 1)))
        EXPECT_FALSE(expected[0].hit());
}

// Finding 17 (docs/robustness.md): a sphere of radius 3e-41 at the origin and a ray passing 1.4e-30 from
// its centre. In float both squares underflowed to 0, the discriminant 0 - 0 said tangent, and brute force
// reported a hit that the grid, whose box lies 1e-30 away from the ray, never tests. The sphere test is now
// computed in double: no hit, and a ray through the centre still hits.
TEST(FuzzRegression, TinySphereIsNotTouchedFromAfar) {
    const TestScene scene{"tiny sphere", {}, {{{0, 0, 0}, 0x1.81p-135f, 0}}};
    const std::vector<Ray> rays = {
        {Vec3f(0x1.4484cp-100f), {0x1.4484cp-100f, 0x1.4484cp-100f, 0x1.ep-1f}, -1, 1},  // 1.4e-30 away
        {{0, 0, 1}, {0, 0, -1}, 0, kInfinity}};                                          // through the centre
    for (const std::vector<Hit>& expected : expect_every_structure_agrees(scene, rays)) {
        EXPECT_FALSE(expected[0].hit());
        EXPECT_TRUE(expected[1].hit());
    }
}

// Finding 33 (docs/robustness.md): a line from a triangle's vertex at the coordinate limit, nearly in the
// triangle's plane. The watertight test's exact path took t from the plane, n . (v0 - o) / n . d, two
// cancellations whose quotient put the vertex at t = 8/7 2^60 instead of 0: brute force reported that hit
// for tnear = 7/8, which the trees' boxes, passed at t = 0, never asked for. The vertex is hit at t = 0
// exactly, and from tnear = 7/8 the line misses.
TEST(FuzzRegression, AGrazingLineFromAVertexMeetsItAtZero) {
    const float limit = 0x1.fffffep+59f;
    const TestScene scene{
        "a vertex at the coordinate limit", {{{-2.625f, -2.625f, 1}, {-5, -3, limit}, Vec3f(limit)}}, {}};
    const Vec3f direction(limit, limit, -0.875f);
    const std::vector<Ray> rays = {{Vec3f(limit), direction, 0, kInfinity},
                                   {Vec3f(limit), direction, 0.875f, kInfinity}};
    for (const std::string_view name : accel_names()) {
        if (name.starts_with("embree")) continue;
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(scene.geometry(), build_options(test));
            const std::vector<Hit> hits = trace(*accel, rays);
            EXPECT_FALSE(hits[1].hit()) << name << ", t = " << hits[1].t;
            // Moller-Trumbore is not watertight and may miss the vertex; where it is reported, it is at 0.
            if (test == TriangleTest::MollerTrumbore && !hits[0].hit()) continue;
            EXPECT_EQ(hits[0].prim, 0) << name;
            EXPECT_EQ(hits[0].t, 0.0f) << name;
            EXPECT_EQ(hits[0].v, 1.0f) << name;
        }
    }
}

// Finding 36 (docs/robustness.md): a line in the plane y = z, which holds edge 0-1 of triangle 0 while its
// third vertex lies 2^-78 off it, so that the line meets the triangle's plane only on that edge, at t =
// -1.41424 (u = 0.84466, exact arithmetic). Both edge functions of the other edges vanished in double, and
// the exact path, weighing the depths by them, took each corner's share: the edge's midpoint, t = 9.5, a hit
// inside [-0.1875, inf] that brute force reported and the grid did not. The hit on an edge is now where the
// line meets the edge's line: from tnear = -0.1875 every structure misses, from -5 the watertight ones hit
// there.
TEST(FuzzRegression, ALineMeetingAnEdgeIsHitThereNotAtItsMiddle) {
    const float tiny = 0x1.4484cp-100f;
    const TestScene scene{"a line in the plane of an edge",
                          {{{-0x1.3cp+2f, 0.5f, 0.5f}, {1, 0, 0}, {0x1.f8p+1f, -0x1.5b5b5ap-78f, tiny}},
                           {Vec3f(tiny), {tiny, -0x1p-149f, tiny}, Vec3f(tiny)}},
                          {{Vec3f(tiny), tiny}, {{tiny, -0x1.ff315ap-96f, tiny}, tiny}}};
    const Vec3f point(-0x1.8p-3f);
    const std::vector<Ray> rays = {{point, point, -0x1.8p-3f, kInfinity}, {point, point, -5, kInfinity}};
    const std::vector<std::vector<Hit>> expected = expect_every_structure_agrees(scene, rays);
    for (const std::vector<Hit>& hits : expected)
        EXPECT_FALSE(hits[0].hit()) << "t = " << hits[0].t;
    const Hit& watertight = expected[1][1];
    EXPECT_EQ(watertight.prim, 0);
    EXPECT_NEAR(watertight.t, -1.4142395f, 1e-6f);
    EXPECT_NEAR(watertight.u, 0.84466f, 1e-5f);
    EXPECT_EQ(watertight.v, 0.0f);
}

// Finding 35 (docs/robustness.md): the icosphere stretched by 2^12 along x, and a ray that crosses triangle
// 588 (556 units long, 0.2 wide) at 2 degrees. The float watertight test, its three edge functions certain,
// weighed the vertices' depths with their products' rounding, up to 2^-24 N^2 (N near 460): t = -0.0034 for
// the exact +0.0085, a point 0.1 outside the triangle's box. Brute force answered it before the right hit,
// triangle 169 at t = -2.0102e-8 (exact arithmetic), and a `bvh` with one triangle a leaf culled it. The
// edge functions are now Kahan's differences of products, within 2 2^-24 of their own magnitude: every
// structure answers triangle 169, and from tnear = 1e-6, past it, triangle 588 near its exact t.
TEST(FuzzRegression, ALongThinTriangleCrossedAtAGrazingAngleIsHitWhereTheLineMeetsIt) {
    TriangleMesh mesh = make_icosphere(3);
    for (Vec3f& position : mesh.positions)
        position.x *= 0x1p12f;
    const TestScene scene{"stretched icosphere", mesh.triangles(), {}};
    const Vec3f origin(0x1.79e41cp+9f, 0x1.6d9858p-1f, -0x1.58365ep-1f), direction(-5, -5, -0x1.3cp+2f);
    const std::vector<Ray> rays = {{origin, direction, -0x1.3cp+2f, 0x1.fffffep+127f},
                                   {origin, direction, 1e-6f, 0x1.fffffep+127f}};
    const std::vector<std::vector<Hit>> expected = expect_every_structure_agrees(scene, rays);
    const std::vector<Hit>& watertight = expected[1];
    EXPECT_EQ(watertight[0].prim, 169);
    EXPECT_NEAR(watertight[0].t, -2.0102477e-8f, 1e-10f);
    EXPECT_EQ(watertight[1].prim, 588);
    // Within an ulp of the hit's x (2^-14 near x = 755; d.x = -5), the contract's "a few ulps of the hit
    // point's coordinates": the sheared vertices' rounding, seen at 2 degrees, leaves 4.1e-6. Without the
    // fix, t was 0.012 off.
    EXPECT_NEAR(watertight[1].t, 0.0084838557f, 0x1p-14f / 5.0f);
    // The harness's deep options: one triangle a leaf, whose box is the triangle's own.
    BuildOptions deep = build_options(TriangleTest::Watertight);
    set_build_option(deep, "bvh.max_leaf_size=1");
    for (const std::string_view name : {"bvh", "bvh8", "bvh8_packet"}) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(scene.geometry(), deep);
        EXPECT_EQ(compare_hits(rays, watertight, trace(*accel, rays)).mismatches, 0u) << name;
    }
}

}  // namespace
}  // namespace lancer
