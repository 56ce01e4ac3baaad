// The inputs fuzz/rays_fuzz.cpp found, replayed in the normal suite (docs/robustness.md, "Fuzzing"): every
// structure agrees with brute force on them (0 mismatches); every hit lies in [tnear, tfar]; Embree, where
// its domain and kernels allow (FuzzCase::embree_agrees), agrees within its own rounding (embree_test.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "fuzz_regression.hpp"
#include "lancer/accel.hpp"
#include "lancer/agreement.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using fuzz_regression::any_hit;
using fuzz_regression::expect_every_structure_agrees;
using fuzz_regression::trace;
using testing::TestScene;

struct FuzzCase {
    TestScene scene;
    std::vector<Ray> rays;
    // false: Embree is only asked for clean answers (hits inside [tnear, tfar]), not brute force's: the rays
    // start beyond 2^60, outside its domain where embree.cpp answers misses, hit exactly at a vertex, which
    // its own kernels may miss, or touch a sphere only through its float rounding.
    bool embree_agrees = true;
};

// The fuzzer's inputs, hex floats as LANCER_FUZZ_PRINT=1 prints them.
std::vector<FuzzCase> fuzz_cases() {
    const Vec3f corner(-0x1.4p+2f);  // (-5, -5, -5)
    return {
        // A scene that is one point: the Plücker octree's root cube has size 0, and cell_index converted
        // the NaN (p - lo) / size to an integer (UBSan: walk.hpp; fixed to start from cell 0).
        {{"one-point scene", {{corner, corner, corner}}, {}},
         {{corner, {-5.0f, -5.0f, 0x1.017e14p-126f}, -5.0f, 0x1.1p+0f},
          {corner, {1.0f, 0.0f, -5.0f}, 0x1.2p+2f, 0x1.2p+2f},
          {corner, corner, -5.0f, -5.0f}}},
        // A negative tnear, valid under the contract: Embree asserts tnear >= 0 (embree.cpp now starts such a
        // ray at o + tnear d); the hit behind the origin at t = -1 must be found.
        {{"hit behind the origin", {{{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}}}, {}},
         {{{0, 0, 1}, {0, 0, 1}, -5.0f, kInfinity}, {{0, 0, 1}, {0, 0, 1}, -5.0f, -1.5f}}},
        // A ray whose whole interval [0, 0] lies 1 unit outside the scene's box, inside its geometric
        // tolerance (2^40 here): the float sphere kernel reported a hit at t = 0 by rounding, and the
        // octree's walk, which did not grow its root by the tolerance, missed it. Since finding 17 the
        // sphere test runs in double and every structure answers the exact miss; Embree's float test still
        // reports the rounded hit, so it is asked for clean answers only.
        {{"interval in the tolerance margin",
          {{{1, 0x1.a0a02p+33f, 0x1p+24f}, {0x1p+24f, 0x1p+24f, 0x1p+24f}, {0x1p+24f, 0x1p+60f, 0x1p+24f}}},
          {{{0x1p+24f, 0x1p+24f, 0x1p+24f}, 0x1p+24f, 0}, {{0x1p+24f, 0x1p+24f, 0x1p+24f}, 0x1p+24f, 0}}},
         {{{0x1p+24f, 0x1p+24f, -1}, {-1, 1, 1}, 0, 0}},
         false},
        // A ray from 6.5e19 away through a vertex, its whole path through the scene within an ulp of
        // t = -1.08: the slab exits were widened by multiplying by 1 + 2 gamma(3), which shrinks a negative
        // distance, and the grid, the Plücker octree and the BVHs lost the box (intersect_box).
        {{"far origin, negative t",
          {{{0, 0, 0}, {1, 0, 0x1.c0a0ap-35f}, {1, 0, 0}}, {{1, 0, 0}, {1, 0, -5}, {0.5f, 0.5f, 1}}},
          {{{-0x1.4p-2f, -1, 0}, 0x1.3cp+2f, 0}, {{0, 0, 0}, 1, 0}}},
         {{{0, 0x1.c0a0ap+65f, 0}, {0, 0x1.a0a0cp+65f, 0}, -5.0f, 0.5f}},
         false},
        // A ray starting on a vertex with [tnear, tfar] = [-0.9375, 0]: Embree, given the ray from
        // o + tnear d, found the vertex at t = 0.9375 and the shift back rounded it an ulp past tfar = 0.
        {{"Embree's shift back past tfar",
          {{Vec3f(-5.0f), Vec3f(-5.0f), Vec3f(-5.0f)},
           {{0, 0, 1}, {-1, -0x1.ep-1f, 0x1.ep-1f}, {-0x1.ep-1f, -5, -0x1.5p+1f}},
           {{-1, -5, -0x1.3p+2f}, {1, 0.5f, 0x1.ep-1f}, {1, -1, -0x1.ep-1f}},
           {{0x1.ep-1f, -0x1.ep-1f, -1}, {0x1.ep-1f, -0x1.ep-1f, -0x1.ep-1f}, {1, -1, -5}}},
          {{{1, 0.5f, 0x1.ep-1f}, 1, 0}}},
         {{{-1, -0x1.ep-1f, 0x1.ep-1f}, {-1, -0x1.ep+0f, 1}, -0x1.ep-1f, 0}},
         false},
        // Directions whose components are all denormal: Embree asserted `ray.valid()` and aborted. Ray
        // conditioning (src/core/ray_conditioning.hpp) now scales such a direction into [1/2, 1) before any
        // structure sees it, Embree included.
        {{"denormal directions",
          {{{2, -5, 2}, {-5, 0x1p-149f, 0x1p-149f}, Vec3f(0x1p-149f)}},
          {{Vec3f(0x1p-149f), 0x1p-149f, 0}, {Vec3f(0x1p-149f), 0x1p-149f, 0}}},
         {{{0x1p-149f, -0x1.08p+1f, 0x1p-149f}, Vec3f(0x1p-149f), 0, kInfinity},
          {{0.5f, 0x1p-149f, 0x1p-149f}, Vec3f(0x1p-149f), 0x1p-149f, 0x1p-149f},
          {{-1, -1, -1}, {0x1p-140f, 0x1p-141f, 0x1p-142f}, 0, kInfinity}},
         false},  // ray 0 crosses the first triangle on its edge: Embree's kernel and ours round differently
        // A direction with a FLT_MAX component and [tnear, tfar] = [-5, 0], which ray conditioning turns
        // into a unit direction with denormal x and y: Embree's triangle test, which expects denormals
        // flushed to zero, reported a hit at t = NaN, and its sphere traversal asserted `ray.valid()` and
        // aborted the process (finding 18; embree.cpp now sets the mode around its queries). The line
        // touches triangle 1 only on its edge at t = tfar = 0, through denormal edge functions: Moller-
        // Trumbore misses it by rounding; the watertight test, which decides such edge functions in double
        // since finding 22, finds it. Embree's float kernel misses it, so it gives clean answers only.
        {{"largest float direction, negative tnear",
          {{{0, 0, 0}, {1, 1, 0x1.48p+1f}, {0, 0, 1}}, {{0, 0, 0}, {0, 1, 1}, {0, 0, -0x1.8p+1f}}},
          {{{-0x1.4p+2f, 0.5f, -0x1.24p+2f}, 1}, {{0, 0, 0x1.02c0cp+33f}, 1}}},
         {{{0, 0, -1}, {0x1p-2f, -0x1.88p+1f, 0x1.fffffep+127f}, -0x1.4p+2f, 0}},
         false},
        // A sliver 3e16 long (triangle 4) in a scene of unit triangles: Embree's float triangle test
        // overflowed (T = Ng . (v0 - o) ~ 2^165) and returned t = NaN, on which its sphere traversal aborted
        // (finding 19; embree.cpp now gives Embree the scene scaled into its range, see
        // Embree.HugeAndTinyScenesAreScaledIntoItsRange). The second ray's exact line crosses the sliver's
        // plane at t = -0.999995, outside it by v = -1e-16 (rational arithmetic), and hits triangle 7 at
        // t = -0.9999988, which brute force finds. Embree's float test reports the sliver at t = -1, within
        // its rounding on a triangle that long, so Embree gives clean answers only.
        {{"scene 3e16 across",
          {{{-1, -1, 1}, {-1, -0x1.ep-1f, 0x1.ep-1f}, {-0x1.ep-1f, -1, 0x1.ep-1f}},
           {{-0x1.ep-1f, -0x1.ep-1f, 1}, {-0x1.28p+2f, -5, -0x1.ep-1f}, {-1, -0x1.6p+0f, 0x1.18p+1f}},
           {{0x1.5p+0f, 0x1.7p+0f, 0x1.1p+0f}, {0, -5, -5}, {-0x1.5p+1f, -5, -5}},
           {{0x1.81d818p-127f, -5, -5},
            {-0x1.24p+2f, -0x1.ep+0f, -5},
            {0x1.01018p-127f, -0x1.ep-1f, -0x1.ep-1f}},
           {{1, -1, -0x1.0000cp+53f}, {-2, -5, 0x1.4p-2f}, {0x1.dp+0f, -0x1.b5b5b4p+54f, 0x1.be8084p+3f}},
           {{0x1.cp-1f, -0x1.ep-1f, -0x1.18p+2f}, {-5, -5, -5}, {-5, -5, -0x1.24p+2f}},
           {{-5, -0x1.3cp+2f, -1}, {-0x1.cp-1f, -0x1.3p+1f, -0x1.ep-1f}, {-0x1.ep-1f, 0x1.cp-1f, -0x1.ep-1f}},
           {{-0x1.cp-1f, 0x1.ep-1f, -1}, {-0x1.ep-1f, -4, 1}, {1, -5, 1}}},
          {{{-0x1.28p+2f, -5, -5}, 0x1.24p+2f}}},
         {{{-0x1.ep+0f, -5, 0x1.8c8c8p-129f}, Vec3f(-0x1.91919p+18f), -0x1.91919p+18f, -0x1.91919p+18f},
          {Vec3f(-0x1.91919p+18f), Vec3f(-0x1.91919p+18f), -0x1.91919p+18f, 0x1.3p-142f}},
         false},
        // Origin and direction (FLT_MAX, FLT_MAX, FLT_MAX): the diagonal through the vertex (0, 0, 0) of a
        // sliver 1.4e-38 wide (triangle 1), at t = -1. Scaled, the direction is 1 - 2^-24, the scene at
        // t' = -2^128: ray conditioning refused a shift beyond the float range and left the origin at
        // FLT_MAX, where brute force's Moller-Trumbore found the vertex by rounding and every other
        // structure missed (finding 20). Moved with a double shift, every structure and both tests find the
        // vertex at t = -1. Triangle 0 is crossed 1.5e-39 later, which rounds to the same t: Embree, whose
        // denormals-are-zero mode flattens the sliver, reports that one, so it gives clean answers only.
        {{"origin and direction at FLT_MAX",
          {{{-0x1.cp+0f, 0x1.8p+0f, 0x1.3p+1f}, {0x1.2p+0f, 0, 0}, {1, 1, 0}},
           {{0, 0, 1}, {0x1.81016p-127f, 0, 1}, {0, 0, 0}}},
          {}},
         {{Vec3f(0x1.fffffep+127f), Vec3f(0x1.fffffep+127f), -0x1.5p+1f, kInfinity}},
         false},
        // From (-FLT_MAX, -FLT_MAX, -FLT_MAX) along (0.8125, 0.8125, 0.8125): the scene lies at t = 4.2e38,
        // beyond the float range, so the ray hits nothing. Since fix 20 its origin is moved with a shift of
        // 4.2e38; closest hit maps the hit back to no hit, but occluded, which maps nothing back, reported
        // the ray blocked (finding 21): the moved interval now ends where the caller's t would overflow.
        {{"scene beyond the float range",
          {{Vec3f(-0x1.48p+1f), {-0x1.48p+1f, -1, -1}, Vec3f(-1)},
           {{-1, 0x1.08p+1f, -5}, Vec3f(-5), Vec3f(-1)}},
          {{{-1, -1, -5}, 5}}},
         {{Vec3f(-0x1.fffffep+127f), Vec3f(0x1.ap-1f), 0x1.ap-1f, kInfinity},
          {Vec3f(-5), {-5, -0x1.ep-1f, -0x1.ep-1f}, -0x1.ep-1f, kInfinity}}},
        // A sliver 2^-126 wide (triangle 1), crossed at t = 2^-24 from (-1, 0, 0) along (2^24, 0.625, 3e-39),
        // the interval [-1.2e-15, 2^-126] ending before it: the watertight kernel's numerator underflowed and
        // said t = 0, a hit that brute force and the structures whose cells hold the origin reported and the
        // kd-tree and the BVHs did not (finding 22). Edge functions and numerators in the denormal range are
        // now computed in double: every structure answers the miss.
        {{"denormal edge functions",
          {{{0, 0.5f, 0.5f}, {0, 0, 0}, {-0x1.3cp+2f, 0.5f, 0.5f}},
           {Vec3f(0x1p-126f), {0x1p-126f, 1, 0}, {0, 0, 0}}},
          {}},
         {{{-1, 0, 0}, {0x1p+24f, 0x1.4p-1f, 0x1.02fff8p-128f}, -0x1.4d4d4cp-50f, 0x1p-126f},
          {{-1, 0, 0}, {0x1p+24f, 0x1.4p-1f, 0x1.02fff8p-128f}, -0x1.4d4d4cp-50f, kInfinity}}},
        // A needle (one vertex at z = 2^24, the rest within 5 units) seen from 4.3e8 away along the diagonal:
        // the exact line passes 207 units from the vertex (-3.0625, -5, -5) of triangle 2. The float Moller-
        // Trumbore test reported it (u = v = 0, t = -1), and so did brute force, the octrees and the kd-tree,
        // not the grid, the BVHs or Embree, which culled it with the geometric tolerance (16 units then).
        // Finding 23: Moller-Trumbore decides within its error bound of an edge in double, and ray
        // conditioning moves origins beyond 8 times the largest coordinate (this one is 25 times it).
        {{"needle seen from 25 times its length",
          {{{0x1.5p+0f, 1, 0}, {0, 0, 0}, {0, 0, 0}},
           {corner, {-5, -5, 0x1p+24f}, {0, -1, 0}},
           {{-0x1.88p+1f, -5, -5}, corner, {-5, -5, -0x1.3cp+2f}},
           {{0.5f, 0.5f, 1}, {0, 0, -1}, {2, -5, 1}},
           {{0, 0, 1}, {0, -5, 0.5f}, {0.5f, 1, 0}},
           {{0, -1, -5}, corner, corner},
           {corner, {-5, -5, 0x1.1p+0f}, {2, 0x1.5p+0f, 0x1.7p+0f}},
           {{0x1.28p+1f, -5, -5}, {-5, -5, -0x1.fp+0f}, corner}},
          {}},
         {{{-0x1.9b9b8ap+28f, -0x1.9b9b9ap+28f, -0x1.9b9b9ap+28f},
           Vec3f(-0x1.9b9b9ap+28f),
           -0x1.9b9b9ap+28f,
           kInfinity}}},
        // The same error from inside a unit scene (scratch search after finding 23, rays aimed just outside
        // the vertices): the float Moller-Trumbore test reported this triangle at t = 1 for a line that
        // misses its box grown by the tolerance then (2^-20); brute force and the kd-tree answered the hit,
        // every other structure the miss.
        {{"Moller-Trumbore's rounding beside a vertex",
          {{{-0x1.e12ec8p-1f, 0x1.2ce9a8p-2f, 0x1.81be3cp-1f},
            {0x1.bba48p-4f, 0x1.b8238p-5f, 0x1.27516p-3f},
            {-0x1.b1aa14p-2f, 0x1.570c4cp-3f, 0x1.c68f9ap-2f}}},
          {}},
         {{{0x1.c3756ep-2f, 0x1.3044ecp-1f, -0x1.2dbfb6p-1f},
           {-0x1.548beap-2f, -0x1.14c2bcp-1f, 0x1.7793e8p-1f},
           0,
           kInfinity}}},
        // A ray from a point of a triangle with tnear the smallest denormal (finding 26): Embree, which runs
        // with denormals read as zero, took tnear as 0 and reported the triangle at t = 0, behind tnear;
        // brute force answers the miss. Then the empty interval [2^-148, 2^-149], an invalid ray that Embree
        // saw as [0, 0] and hit. Sixteen copies of each, so that Embree's 16-wide structure takes full
        // packets
        // (its SIMD fast path) as well as the one-ray path.
        {{"denormal tnear on the surface", {{{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}}}, {}},
         [] {
             std::vector<Ray> rays(16, Ray{{0, 0, 0}, {0, 0, 1}, 0x1p-149f, 1});
             rays.resize(32, Ray{{0, 0, 0}, {0, 0, 1}, 0x1p-148f, 0x1p-149f});
             return rays;
         }(),
         false},  // Embree gives clean answers only: its hit at t = 0 comes back clamped to tnear
    };
}

TEST(FuzzRegression, EveryStructureAgreesWithBruteForce) {
    for (const FuzzCase& fuzz_case : fuzz_cases()) {
        const Geometry geometry = fuzz_case.scene.geometry();
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            const std::unique_ptr<Accel> brute = make_accel("brute");
            brute->build(geometry, build_options(test));
            const std::vector<Hit> expected = trace(*brute, fuzz_case.rays);
            for (const std::string_view name : accel_names()) {
                const std::unique_ptr<Accel> accel = make_accel(name);
                accel->build(geometry, build_options(test));
                const std::vector<Hit> hits = trace(*accel, fuzz_case.rays);
                std::vector<std::uint8_t> occluded(fuzz_case.rays.size());
                accel->occluded(fuzz_case.rays, occluded);
                const std::string context = fuzz_case.scene.name + ", " + std::string(name);
                for (std::size_t i = 0; i < hits.size(); ++i) {
                    if (!hits[i].hit()) continue;
                    EXPECT_GE(hits[i].t, fuzz_case.rays[i].tnear) << context << ", ray " << i;
                    EXPECT_LE(hits[i].t, fuzz_case.rays[i].tfar) << context << ", ray " << i;
                }
                if (name.starts_with("embree") && !fuzz_case.embree_agrees) continue;
                EXPECT_EQ(compare_occlusion(fuzz_case.rays, expected, occluded).mismatches, 0u) << context;
                if (!name.starts_with("embree")) {
                    EXPECT_EQ(compare_hits(fuzz_case.rays, expected, hits).mismatches, 0u) << context;
                    continue;
                }
                for (std::size_t i = 0; i < hits.size(); ++i) {
                    ASSERT_EQ(hits[i].hit(), expected[i].hit()) << context << ", ray " << i;
                    if (hits[i].hit()) {
                        EXPECT_NEAR(hits[i].t, expected[i].t, 1e-5f) << context << ", ray " << i;
                    }
                }
            }
        }
    }
}

// The second case's point: the answer is a hit at t = -1, not a miss (the check above would pass on misses).
TEST(FuzzRegression, NegativeTnearFindsTheHitBehindTheOrigin) {
    const FuzzCase behind = fuzz_cases()[1];
    for (const std::string_view name : accel_names()) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(behind.scene.geometry(), {});
        const std::vector<Hit> hits = trace(*accel, behind.rays);
        EXPECT_EQ(hits[0].prim, 0) << name;
        EXPECT_NEAR(hits[0].t, -1.0f, 1e-6f) << name;
        EXPECT_FALSE(hits[1].hit()) << name << ": tfar = -1.5 ends before the triangle";
    }
}

// Finding 32 (docs/robustness.md): a scene 1.2e14 wide is held at scale 2^-47, where a sphere of radius
// FLT_MIN shrinks to nothing, is never hit and leaves the scaled box. A packet structure built its
// single-ray structure through build(), which derived a scale of its own (2^44) from that smaller box: its
// kernels walked a copy at another scale than the rays, and bvh8_packet and plucker_packet missed the
// triangle behind the ray's origin. Every structure finds it at t = -5/3.
TEST(FuzzRegression, PacketStructuresHoldTheirSceneAtTheRaysScale) {
    const TestScene scene{"a sphere that scaling shrinks to nothing",
                          {{{0, 0, 1}, {1, -5, -5}, {-5, -5, -5}}},
                          {{{-0x1.adacap+46f, 1, 0x1p-126f}, 0x1p-126f}}};
    const std::vector<Ray> rays = {{{0x1p-126f, 0x1p-126f, 0x1p-126f}, {0, 0.5f, 0}, -0x1.3cp+2f, 1}};
    for (const std::vector<Hit>& expected : expect_every_structure_agrees(scene, rays)) {
        EXPECT_EQ(expected[0].prim, 0);
        EXPECT_FLOAT_EQ(expected[0].t, -5.0f / 3.0f);
    }
}

// Finding 20's point: the vertex at t = -1 is found, not missed (the check above would pass on misses).
TEST(FuzzRegression, OriginAtFloatMaxFindsTheVertexOnItsLine) {
    const std::vector<FuzzCase> cases = fuzz_cases();
    const auto found = std::find_if(cases.begin(), cases.end(), [](const FuzzCase& fuzz_case) {
        return fuzz_case.scene.name == "origin and direction at FLT_MAX";
    });
    ASSERT_NE(found, cases.end());
    const FuzzCase& diagonal = *found;
    for (const std::string_view name : accel_names()) {
        if (name.starts_with("embree")) continue;
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(diagonal.scene.geometry(), build_options(test));
            const Hit hit = trace(*accel, diagonal.rays)[0];
            EXPECT_EQ(hit.prim, 1) << name;
            EXPECT_EQ(hit.t, -1.0f) << name;
        }
    }
}

// Finding 11 (docs/robustness.md): a ray from 4.5e11 away along the diagonal through the origin, which it
// reaches at t = -1; the scene's kernels saw it through a 2^15-unit grid of rounded points and brute force
// reported a 5-unit triangle that the line misses by more than a unit. Far rays are now moved near the scene
// along their line (src/core/ray_conditioning.hpp): every structure answers the exact line's miss.
TEST(FuzzRegression, FarOriginRoundingNoiseIsGone) {
    const TestScene scene{"far origin noise",
                          {{{0, -0x1.3cp+2f, 0}, {0, -0x1.3cp+2f, 0.25f}, {0.75f, -0x1.2p+0f, 0}}},
                          {{{1, 0, -5}, 1, 0}, {{-1, 0.5f, 0}, 1, 0}}};
    const std::vector<Ray> rays = {{Vec3f(-0x1.a5a5a4p+38f), Vec3f(-0x1.a5a5a4p+38f), -1, 1}};
    for (const std::string_view name : accel_names()) {
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(scene.geometry(), build_options(test));
            EXPECT_FALSE(trace(*accel, rays)[0].hit()) << name;
        }
    }
}

// The other side of finding 11: from 2^39 away, a line through the origin, which lies inside triangle 0 (at
// t = 1), passing 0.05 beside triangle 1 (z = 0.5). Every structure finds triangle 0 to a few ulps of t,
// with the barycentrics of the origin, whatever the triangle test.
TEST(FuzzRegression, FarOriginHitsWhatTheLineHits) {
    const TestScene scene{"far origin hit",
                          {{{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}},
                           {{1.0f / 6 + 0.05f, 0.25f, 0.5f}, {0.5f, 0.25f, 0.5f}, {0.5f, 0.5f, 0.5f}}},
                          {}};
    const Vec3f origin(0x1p38f, 0x1p39f, 0x1.8p39f);  // the line's direction (1, 2, 3)
    // The second from the other side, with the hit exactly at tfar (the interval is closed).
    const std::vector<Ray> rays = {{origin, -origin, 0, kInfinity},
                                   {-origin, origin * 0.5f, -std::numeric_limits<float>::max(), 2}};
    const float expected_t[] = {1, 2};
    for (const std::string_view name : accel_names()) {
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(scene.geometry(), build_options(test));
            const std::vector<Hit> hits = trace(*accel, rays);
            const std::vector<std::uint8_t> blocked = any_hit(*accel, rays);
            for (std::size_t i = 0; i < rays.size(); ++i) {
                ASSERT_EQ(hits[i].prim, 0) << name << " ray " << i;
                EXPECT_NEAR(hits[i].t, expected_t[i], 1e-6f) << name;
                // The origin is (1 - u - v) v0 + u v1 + v v2 with u = 1/4, v = 1/2.
                EXPECT_NEAR(hits[i].u, 0.25f, 1e-6f) << name;
                EXPECT_NEAR(hits[i].v, 0.5f, 1e-6f) << name;
                EXPECT_EQ(blocked[i], 1) << name;
            }
        }
    }
}

// Finding 8 (docs/robustness.md): a scene from -FLT_MAX to 2 had no finite octree root cube (lo + size must
// reach hi), and the octree missed a hit near the origin. The contract now bounds coordinates to
// [-2^60, 2^60] (kCoordinateLimit): every structure refuses the scene (as load_scene does), and at the
// bound itself the octree, like every other structure, agrees with brute force. Finding 12 (Embree's abort on
// geometry beyond its range) is the same rule: its build is refused before Embree sees the vertices.
TestScene scene_reaching(float m) {
    return {"float range",
            {{{0, 0, -0x1.3cp+2f}, {1, 0.5f, 0.5f}, {1, 0, 0x1p-4f}},
             {{-1, 2, -5}, {1, 1, m}, Vec3f(m)},
             {Vec3f(m), Vec3f(m), Vec3f(m)},
             {Vec3f(m), {m, 0.3125f, m}, Vec3f(m)},
             {Vec3f(m), Vec3f(m), {m, 0.3125f, 0.1875f}},
             {{-0.5f, 0x1.c8p+1f, 0x1.cp-1f}, {0, -5, 1}, {-1, -5, -0x1.3p+2f}},
             {{1, 0.5f, 0}, {-5, -4, 0}, {-5, 0.5f, 0.5f}},
             {{1, 0, 0}, {-1, 0, -0x1.3cp+2f}, {1, 0.25f, 0.75f}}},
            {{{0, 2, -5}, 1, 0}}};
}

TEST(FuzzRegression, SceneBeyondTheCoordinateDomainIsRefused) {
    const TestScene beyond = scene_reaching(-std::numeric_limits<float>::max());
    const TestScene just_beyond = scene_reaching(std::nextafter(-kCoordinateLimit, -kInfinity));
    const TestScene sphere_beyond{"sphere", {}, {{{0, 0, 0}, 1, 0}, {{0x1p59f, 0, 0}, 0x1p59f + 0x1p40f, 0}}};
    for (const std::string_view name : accel_names()) {
        for (const TestScene* scene : {&beyond, &just_beyond, &sphere_beyond}) {
            const std::unique_ptr<Accel> accel = make_accel(name);
            EXPECT_THROW(accel->build(scene->geometry(), {}), std::invalid_argument)
                << name << " " << scene->name;
        }
    }
}

TEST(FuzzRegression, SceneAtTheCoordinateLimitAgreesWithBruteForce) {
    const TestScene scene = scene_reaching(-kCoordinateLimit);
    const std::vector<Ray> rays = {{{0, 0, 1}, {0, 0, -5}, -0.5f, kInfinity}};
    for (const std::vector<Hit>& expected : expect_every_structure_agrees(scene, rays))
        EXPECT_TRUE(expected[0].hit());
}

// Finding 14 (docs/robustness.md), from a sweep of random 8-triangle scenes (vertices on a 1/16 lattice,
// scaled down) and rays with tiny or huge direction components: rays whose components are denormal (or whose
// largest is barely normal) cross the scene at t near 2^125..2^127. Brute force finds their hits; the grid
// took 1 / d = inf for "never crosses a plane of this axis", stayed in its first cells and answered a miss,
// or a farther triangle (ray 1 of each scene, ray 1 of scene 113 under the watertight test too, ray 4 of
// scene 271). Every structure now sees such a direction scaled by a power of two
// (src/core/ray_conditioning.hpp).
struct TinyDirectionCase {
    TestScene scene;
    std::vector<Ray> rays;
};

std::vector<TinyDirectionCase> tiny_direction_cases() {
    return {
        {{"sweep scene 113",
          {{{-0x1.fp-5f, 0x1.e8p-4f, -0x1.dp-4f},
            {-0x1.18p-4f, -0x1.7p-5f, 0x1.7p-4f},
            {-0x1.ap-5f, 0x1.cp-5f, 0x1.bp-4f}},
           {{-0x1.2cp-3f, 0x1.14p-3f, 0x1.ep-5f},
            {-0x1.6p-6f, 0x1.9p-4f, 0x1p-7f},
            {0x1.cp-5f, -0x1.1p-4f, -0x1.dp-5f}},
           {{-0x1.34p-3f, -0x1.ep-4f, 0x1p-7f},
            {0x1p-4f, -0x1.c8p-4f, -0x1.2cp-3f},
            {-0x1.ap-4f, 0x1.ep-4f, -0x1.dp-4f}},
           {{-0x1.1p-5f, 0x1.5p-4f, -0x1p-3f},
            {0x1.ap-5f, 0x1.78p-4f, -0x1.1p-5f},
            {0x1.4p-4f, -0x1.18p-3f, 0x1.08p-3f}},
           {{0x1.4p-4f, 0x1.38p-4f, 0x1.1p-5f},
            {0x1.ep-6f, 0x1.28p-3f, 0x1.3p-3f},
            {-0x1.4p-6f, 0x1.7p-4f, -0x1.14p-3f}},
           {{0x1.38p-3f, 0x1.e8p-4f, 0x1.fp-5f},
            {-0x1.dp-5f, -0x1.1p-5f, 0x1.7p-4f},
            {0x1.bp-4f, 0x1.8p-6f, -0x1.8p-4f}},
           {{0x1.8p-7f, -0x1.2p-4f, 0x1.3p-4f},
            {-0x1.4p-3f, -0x1.6p-5f, -0x1.1cp-3f},
            {0x1.4p-7f, -0x1.9p-4f, 0x1.04p-3f}},
           {{0x1.c8p-4f, -0x1.cp-5f, -0x1.8p-4f},
            {0x1.ep-6f, -0x1.4p-7f, 0x1.78p-4f},
            {0x1.3p-4f, -0x1.8p-6f, -0x1.7p-4f}}},
          {}},
         {{{-0x1.2fd89ep-1f, -0x1.0d3b14p-1f, 0x1.14ec5p-3f},
           {0x1.78cd6p-129f, 0x1.98d58p-129f, -0x1.5e066p-130f}},
          {{0x1p-6f, -0x1.cp-7f, -0x1.24p-3f}, {-0x1.2676ap-129f, 0x1.31281p-129f, 0x1.07b068p-128f}},
          {{0x1.cp-6f, 0x1.4p-4f, 0x1.0cp-3f}, {-0x1.77dadp-129f, -0x1.460e7p-129f, -0x1.30d6cp-130f}},
          // The octree, the Plücker octree and the BVHs lost this one too (their boxes' 1 / d of a denormal
          // component): rays are now conditioned once for every structure (src/core/ray_conditioning.hpp).
          {{-0x1.1c9d8ap-1f, -0x1.ec4ec6p-3f, 0x1.9p-2f},
           {0x1.83e9a8p-128f, 0x1.41f5p-129f, -0x1.d368ep-129f}}}},
        {{"sweep scene 271",
          {{{-0x1.2p-6f, -0x1.ap-8f, -0x1.68p-6f},
            {-0x1.88p-6f, 0x1.4p-6f, -0x1.8p-9f},
            {0x1.6p-8f, 0x1.2p-7f, 0x1.ep-6f}},
           {{0x1.3cp-5f, 0x1.5p-6f, -0x1.5p-7f},
            {0, -0x1.e8p-6f, 0x1.ep-8f},
            {0x1.c8p-6f, 0x1.ap-6f, 0x1.0cp-5f}},
           {{0x1.3p-7f, -0x1.ep-8f, 0x1.6p-6f},
            {0x1.28p-5f, 0x1p-5f, -0x1.18p-6f},
            {0x1.dp-6f, -0x1.5p-6f, 0x1.7p-7f}},
           {{-0x1.1p-5f, -0x1.ap-6f, -0x1.fp-7f},
            {-0x1.fp-7f, -0x1.4p-7f, -0x1.4p-6f},
            {-0x1.ep-7f, 0x1.ap-7f, -0x1.68p-6f}},
           {{-0x1.58p-6f, 0x1.18p-6f, 0x1p-6f},
            {-0x1.e8p-6f, -0x1.78p-6f, 0x1.6p-6f},
            {-0x1.4p-7f, -0x1p-9f, 0x1.28p-6f}},
           {{-0x1.5p-6f, -0x1.cp-8f, -0x1.4p-6f},
            {0x1.5p-6f, 0x1.8p-7f, 0x1.9p-6f},
            {-0x1.b8p-6f, 0x1.e8p-6f, -0x1.7p-7f}},
           {{-0x1.58p-6f, 0x1.78p-6f, 0x1.18p-5f},
            {0, -0x1.38p-6f, -0x1.38p-6f},
            {0x1.cp-9f, 0x1.ep-8f, 0x1.ap-8f}},
           {{0x1.4p-6f, 0x1.1p-5f, 0x1.8p-7f},
            {0x1.3p-6f, -0x1.a8p-6f, -0x1.dp-7f},
            {0x1.38p-5f, -0x1.98p-6f, -0x1.7p-7f}}},
          {}},
         {{{-0x1p-11f, 0x1.cp-9f, -0x1.48p-6f}, {0x1.1c178p-132f, 0x1.3b52p-133f, 0x1.8f12p-134f}},
          {{-0x1.08p-5f, -0x1.38p-5f, 0x1.b8p-6f}, {0x1.713p-132f, 0x1.3e646p-130f, -0x1.379e2p-130f}},
          {{-0x1.2p-7f, -0x1.88p-6f, 0x1.28p-5f}, {-0x1.dd878p-132f, 0x1.8671cp-131f, -0x1.72c18p-131f}},
          {{-0x1.ep-7f, 0x1.3p-5f, -0x1.ep-8f}, {0x1.1eccp-133f, -0x1.44ad8p-131f, 0x1.249cp-134f}},
          {{-0x1.24p-5f, 0x1.6p-6f, 0x1.8p-8f}, {0x1.934a6p-130f, -0x1.f6b7p-132f, 0x1.0648cp-131f}},
          {{0x1.88p-6f, -0x1.7p-6f, 0x1.0cp-5f}, {-0x1.14bap-133f, 0x1.0bf4p-133f, -0x1.2b66p-134f}}}},
    };
}

TEST(FuzzRegression, TinyDirectionsFindWhatBruteForceFinds) {
    for (const TinyDirectionCase& tiny : tiny_direction_cases()) {
        // Every ray hits (far out in t), under Moller-Trumbore at least.
        const std::vector<Hit> expected = expect_every_structure_agrees(tiny.scene, tiny.rays).front();
        for (std::size_t i = 0; i < expected.size(); ++i)
            EXPECT_TRUE(expected[i].hit()) << tiny.scene.name << ", ray " << i;
    }
}

// Finding 15 (docs/robustness.md): a ray straight down -y along the scene's x-min face, with a denormal z
// and tnear = -2^60, through the vertex (-5, -5, -4.9375) of triangle 0 (after conditioning,
// d = (-2^-61 1.375, -0.87, 0)). Its exact line leaves the scene box through x = -5 at t = 0 but stays inside
// the entry box, grown by the tolerance, until long after the vertex: the grid, whose walk left at the
// scene box's face, missed the vertex that brute force finds. Its outer cells now reach the entry box.
TEST(FuzzRegression, GridFindsAVertexOnTheBoxFace) {
    const TestScene scene{
        "vertex on the box face",
        {{{0x1.cp-1f, -0x1.9p+1f, -0x1.4p+2f}, Vec3f(-5), {-5, -5, -0x1.3cp+2f}},
         {{-0x1.cp-1f, 0x1.cp-1f, 0x1.ep-1f}, {-1, 0x1.ep-1f, -0x1.ep-1f}, {-0x1.ep-1f, -5, -4}}},
        {{{-4, 1, 1}, 1, 0}}};
    const std::vector<Ray> rays = {
        {{-5, 0, -0x1.3cp+2f}, {-0x1.6p+0f, -0x1.bbbbbap+60f, 0x1.1p-145f}, -0x1.bbbbbap+60f, kInfinity}};
    EXPECT_EQ(expect_every_structure_agrees(scene, rays).front()[0].prim, 0);
}

// Finding 24 (docs/robustness.md, from fuzz/mesh_rays_fuzz.cpp): a ray from a vertex of an icosphere at
// y = 0, a plane of every level of the Plücker octree, towards the centre with d_y = -2^-147. The exact line
// crosses y = 0 at the vertex, at t = 0. The walk, one cell before the vertex's, chose the exit face from
// three Plücker products in float; with w_y = 0 one of them is d_y w_z alone, which underflowed to 0, and
// the pattern named the y face (exit at t = 0) instead of the z face (t = -0.07): the walk stopped with the
// hit at t = 0 on triangle 527, where brute force found triangle 514 at t = -7.5e-19 (Moller-Trumbore) and
// triangle 513 at t = -0 (watertight, lower index). The products are now computed in double. Rays from
// every vertex with a zero coordinate, towards the centre with that component made ±2^-147 or ±2^-130.
TEST(FuzzRegression, PluckerWalkLeavesByTheFirstExitWithADenormalComponent) {
    TestScene scene{"icosphere, denormal components", {}, {}};
    make_icosphere(3).append_triangles(scene.triangles);
    std::vector<Ray> rays = {
        {{-0x1.6c2d1ep-1f, 0, -0x1.67e36ep-1f}, {0x1.6c2d1ep-1f, -0x1p-147f, 0x1.67e36ep-1f}, -5, kInfinity}};
    for (const Triangle& triangle : scene.triangles) {
        for (const Vec3f& vertex : {triangle.v0, triangle.v1, triangle.v2}) {
            for (int axis = 0; axis < 3; ++axis) {
                if (vertex[axis] != 0.0f) continue;
                for (const float tiny : {0x1p-147f, -0x1p-147f, 0x1p-130f, -0x1p-130f}) {
                    Vec3f direction = -vertex;
                    direction[axis] = tiny;
                    rays.push_back({vertex, direction, -5, kInfinity});
                    rays.push_back({vertex, direction, 0, kInfinity});
                }
            }
        }
    }
    ASSERT_GT(rays.size(), 1000u);
    for (const std::vector<Hit>& expected : expect_every_structure_agrees(scene, rays)) {
        for (const Hit& hit : expected)
            EXPECT_TRUE(hit.hit());
    }
}

// Finding 25 (docs/robustness.md, from fuzz/mesh_rays_fuzz.cpp): a ray from (8, -8, 16), on two faces of
// the root, straight down with outward components 2^-73 and 2^-125 of its length (after conditioning), to
// the vertex (8, -8, 0.0625) of a large triangle. The exact line passes 2^-68 outside the triangle, within
// the geometric tolerance, and brute force reports the hit. The Plücker walk entered the root (grown by the
// tolerance) but then left the first cell by its x face on the root's boundary, at t = 0, and missed it. The
// faces of the root's boundary are now the grown root's (exit_plane_of). The fuzzer's ray and its mirror
// images at the other corners of the root's top face.
TEST(FuzzRegression, PluckerWalkFollowsTheRootFacesWithinTheTolerance) {
    TestScene scene{"large triangle over an icosphere", {}, {}};
    scene.triangles.push_back({{-8.0f, -8.0f, 0.0625f}, {8.0f, -8.0f, 0.0625f}, {0.0f, 8.0f, 0.0625f}});
    make_icosphere(2).append_triangles(scene.triangles);
    std::vector<Ray> rays;
    for (const float x : {8.0f, -8.0f}) {
        for (const float y : {-8.0f, 8.0f})
            rays.push_back({{x, y, 16}, {x * 0x1.fff5f4p+51f, -y, -0x1.b1fff4p+127f}, 0, kInfinity});
    }
    const std::vector<std::vector<Hit>> expected = expect_every_structure_agrees(scene, rays);
    EXPECT_EQ(expected[0][0].prim, 0);  // Moller-Trumbore reports the vertex (8, -8)
}

// Fuzz finding 27 (docs/robustness.md): from a point of the icosphere's surface, with the interval starting
// behind it, Moller-Trumbore reports triangle 265 at t = -2.4e-17 and triangle 4 at t = -8.3e-18, each a
// rounding error from its triangle. bvh8_packet culled 265 by its exact bounding box and answered 4; its
// triangle boxes are now grown by the geometric tolerance, as the BVHs' node boxes are.
TEST(FuzzRegression, PacketTriangleCullKeepsAHitBesideItsTriangle) {
    TestScene scene{"icosphere", {}, {}};
    make_icosphere(3).append_triangles(scene.triangles);
    const std::vector<Ray> rays = {{{-0x1.846e14p-1f, 0x1.36b1cap-1f, 0x1.e58d82p-3f},
                                    {-0x1.3p+2f, -0x1.4p+2f, -0x1.2cp+2f},
                                    -0x1.4p+2f,
                                    kInfinity}};
    const std::vector<std::vector<Hit>> expected = expect_every_structure_agrees(scene, rays);
    EXPECT_EQ(expected[0][0].prim, 265);  // Moller-Trumbore
    EXPECT_TRUE(expected[1][0].hit());    // watertight
}

// Fuzz finding 28 (docs/robustness.md): on the icosphere stretched 4096 times along x, Embree's fast
// triangle test reported triangle 788 at t = 1 for this ray, whose interval ends one float before 1 (the
// rounding of its reciprocal of the determinant). Every structure's hits lie in [tnear, tfar], Embree's
// included, taken as they are one by one and in a full packet.
TEST(FuzzRegression, EmbreeHitsStayInsideTheInterval) {
    TriangleMesh mesh = make_icosphere(3);
    for (Vec3f& position : mesh.positions)
        position.x *= 0x1p12f;
    TestScene scene{"stretched icosphere", {}, {}};
    mesh.append_triangles(scene.triangles);
    const std::vector<Ray> rays(16, Ray{{-0x1.3cp+2f, -0x1.38p+2f, 0x1.4484cp-100f},
                                        {-0x1.69ad9ep+10f, 0x1.02b004p+2f, -0x1.ae1066p-2f},
                                        0,
                                        0x1.fffffep-1f});
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        for (const std::string_view name : accel_names()) {
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(scene.geometry(), build_options(test));
            const std::vector<Hit> hits = trace(*accel, rays);
            for (const Hit& hit : hits) {
                if (!hit.hit()) continue;
                EXPECT_GE(hit.t, rays[0].tnear) << name;
                EXPECT_LE(hit.t, rays[0].tfar) << name;
            }
        }
    }
}

}  // namespace
}  // namespace lancer
