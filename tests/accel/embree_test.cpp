// Embree behind lancer's interface: the same answers as brute force on random rays (within Embree's own
// rounding), the global primitive numbering, the ray contract, and packets and streams equal to single rays.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::TestScene;

bool has_embree() {
    for (std::string_view name : accel_names()) {
        if (name == "embree") return true;
    }
    return false;
}

TestScene mixed_scene() {
    TestScene scene;
    for (const TriangleMesh& mesh : {make_icosphere(3), make_torus_knot(300, 10)})
        mesh.append_triangles(scene.triangles);
    scene.spheres = {{{2, 0, 0}, 0.5f, 0}, {{-2, 0.5f, 0}, 0.3f, 0}, {{0, 2, 1}, 0.7f, 0}};
    return scene;
}

std::vector<Hit> trace(const std::string& name, const Geometry& geometry, const BuildOptions& options,
                       std::span<const Ray> rays) {
    const std::unique_ptr<Accel> accel = make_accel(name);
    accel->build(geometry, options);
    std::vector<Hit> hits(rays.size());
    accel->intersect(rays, hits);
    return hits;
}

TEST(Embree, AgreesWithBruteForceOnRandomRays) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    const TestScene scene = mixed_scene();
    const testing::RaySet set =
        testing::random_rays(scene.geometry().bounds(), 20000 / testing::kSanitizedShare, 7);
    const float scale = length(scene.geometry().bounds().extent());
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const std::vector<Hit> expected = trace("brute", scene.geometry(), build_options(test), set.rays);
        for (const char* name : {"embree", "embree_stream"}) {
            const std::vector<Hit> actual = trace(name, scene.geometry(), build_options(test), set.rays);
            std::size_t mismatches = 0, hits = 0;
            for (std::size_t i = 0; i < set.rays.size(); ++i) {
                hits += expected[i].hit() ? 1 : 0;
                // Embree's sphere and triangle t carry an absolute rounding error of a few ulps of the
                // scene's size (it does not use our kernels), hence a tolerance scaled by the scene, not by t
                // alone.
                const bool same = expected[i].hit() == actual[i].hit() &&
                                  (!expected[i].hit() || std::fabs(expected[i].t - actual[i].t) <=
                                                             1e-5f * (std::fabs(expected[i].t) + scale));
                if (!same && mismatches++ < 3) {
                    ADD_FAILURE() << "ray " << i << ": brute prim " << expected[i].prim << " t "
                                  << expected[i].t << ", " << name << " prim " << actual[i].prim << " t "
                                  << actual[i].t;
                }
            }
            std::printf("%s vs brute (%s): %zu random rays, %zu hits, %zu mismatches\n", name,
                        test == TriangleTest::Watertight ? "watertight/robust" : "moller/default",
                        set.rays.size(), hits, mismatches);
            EXPECT_EQ(mismatches, 0u);
            EXPECT_GT(hits, 2000u / testing::kSanitizedShare);
        }
    }
}

// memory_bytes is what the structure's own device holds, its BVH included: more than the vertex and index
// buffers (Embree's BVH takes tens of bytes a triangle), the sum of the arrays stats() lists, and not changed
// by a second structure built beside it.
TEST(Embree, MemoryCountsItsBvhAndOnlyItsOwn) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    TestScene scene;
    make_torus_knot(2000, 20).append_triangles(scene.triangles);  // 80,000 triangles
    const std::unique_ptr<Accel> accel = make_accel("embree");
    accel->build(scene.geometry(), {});
    const std::size_t triangles = scene.triangles.size();
    const std::size_t held = accel->memory_bytes();
    const AccelStats stats = accel->stats();
    std::size_t listed = 0, buffers = 0;
    for (const auto& [name, bytes] : stats.memory_by_array) {
        listed += bytes;
        if (name == "embree buffers") buffers = bytes;
    }
    EXPECT_EQ(listed, held);
    EXPECT_GT(buffers, 0u);
    EXPECT_GT(held, buffers + 16 * triangles) << held << " bytes for " << triangles << " triangles";
    const std::unique_ptr<Accel> beside = make_accel("embree");
    beside->build(scene.geometry(), {});
    EXPECT_EQ(accel->memory_bytes(), held);
}

TEST(Embree, SpheresAreNumberedAfterTrianglesAndInvalidRaysMiss) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    const std::vector<Triangle> triangles = {{{-1, -1, -5}, {1, -1, -5}, {0, 1, -5}}};
    const std::vector<Sphere> spheres = {{{10, 0, 0}, 1.0f, 0}, {{0, 0, 0}, 1.0f, 0}};
    const std::vector<Ray> rays = {{{0, 0, 5}, {0, 0, -1}, 0.0f, kInfinity},
                                   {{0, 0, 5}, {0, 0, 0}, 0.0f, kInfinity},
                                   {{0, 0, 5}, {0, 0, -1}, 3.0f, 1.0f}};
    const std::vector<Hit> hits = trace("embree", {triangles, spheres}, {}, rays);
    EXPECT_EQ(hits[0].prim, 2);
    EXPECT_NEAR(hits[0].t, 4.0f, 1e-5f);
    EXPECT_FALSE(hits[1].hit());
    EXPECT_FALSE(hits[2].hit());
}

// Embree's float triangle test multiplies three lengths of the scene, which overflow for a scene 2^55 across
// and underflow for one 2^-100 across (fuzz finding 19): embree.cpp gives it the scene scaled by a power of
// two into its range. The same triangle and sphere at every magnitude give the same hits, t scaled with them.
TEST(Embree, HugeAndTinyScenesAreScaledIntoItsRange) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    for (const int exponent : {-100, -40, 0, 40, 55}) {
        const float size = std::ldexp(1.0f, exponent);
        const std::vector<Triangle> triangles = {
            {Vec3f(-1, -1, 0) * size, Vec3f(1, -1, 0) * size, Vec3f(0, 1, 0) * size}};
        const std::vector<Sphere> spheres = {{Vec3f(3, 0, 0) * size, size, 0}};
        const std::vector<Ray> rays = {{Vec3f(0, 0, 2) * size, {0, 0, -1}, 0.0f, kInfinity},
                                       {Vec3f(3, 0, 5) * size, {0, 0, -1}, 0.0f, kInfinity},
                                       {Vec3f(0, 0, 2) * size, {0, 0, -1}, -kInfinity, size}};
        for (const char* name : {"embree", "embree8", "embree16", "embree_stream"}) {
            for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
                const std::vector<Hit> hits = trace(name, {triangles, spheres}, build_options(test), rays);
                const std::string context = "scene size 2^" + std::to_string(exponent);
                EXPECT_EQ(hits[0].prim, 0) << context;
                EXPECT_NEAR(hits[0].t, 2 * size, 1e-5f * size) << context;
                EXPECT_EQ(hits[1].prim, 1) << context;
                EXPECT_NEAR(hits[1].t, 4 * size, 1e-5f * size) << context;
                EXPECT_FALSE(hits[2].hit()) << context << ": tfar ends before the triangle";
            }
        }
    }
}

TEST(Embree, PacketsAnswerLikeSingleRays) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    const TestScene scene = mixed_scene();
    testing::RaySet set = testing::random_rays(scene.geometry().bounds(), 5003, 9);  // not a multiple of 16
    for (const Ray& hostile : testing::hostile_rays(scene.geometry().bounds()).rays)
        set.rays.push_back(hostile);
    const std::vector<Hit> single = trace("embree", scene.geometry(), {}, set.rays);
    const float scale = length(scene.geometry().bounds().extent());
    for (const char* name : {"embree", "embree8", "embree16", "embree_stream"}) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(scene.geometry(), {});
        // The plain call, the coherent one (Embree's COHERENT flag, which keeps packets together longer) and
        // the packet call, which reads the rays in place.
        std::vector<Hit> packed(set.rays.size()), coherent(set.rays.size());
        accel->intersect(set.rays, packed);
        accel->intersect_coherent(set.rays, coherent);
        std::vector<Hit> in_packets = testing::intersect_in_packets(*accel, set.rays);
        // Occlusion: any hit exactly where rtcIntersect1 finds the closest one.
        std::vector<std::uint8_t> occluded(set.rays.size());
        accel->occluded(set.rays, occluded);
        for (std::size_t i = 0; i < set.rays.size(); ++i)
            ASSERT_EQ(static_cast<int>(occluded[i]), single[i].hit() ? 1 : 0) << name << " ray " << i;
        for (const std::vector<Hit>* answers : {&packed, &coherent, &in_packets}) {
            for (std::size_t i = 0; i < set.rays.size(); ++i) {
                ASSERT_EQ(single[i].prim, (*answers)[i].prim) << name << " ray " << i;
                if (single[i].hit()) {
                    // Embree's packet kernels round differently from its single-ray ones: the same
                    // scene-scaled tolerance as against brute force.
                    ASSERT_NEAR(single[i].t, (*answers)[i].t, 1e-5f * (single[i].t + scale))
                        << name << " ray " << i;
                }
            }
        }
    }
}

// Finding 34 (docs/robustness.md): Embree takes a zero direction component's reciprocal as 1e18 and any
// other's as it is, so a component below 2^-59 overflowed its slab and frustum tests. Its 8- and 16-ray calls
// and its streams then missed occluders (and, under the COHERENT flag, aborted on an empty child). Such rays
// come from ray conditioning (a direction of 2^123 scaled into [1/2, 1) keeps its other components at 2^-121)
// or straight from the caller. Every call now answers brute force's occlusion, and hits as it does within
// Embree's rounding (the first ray starts on a vertex, whose triangles tie).
TEST(Embree, DirectionsWithTinyComponentsAnswerInEveryCall) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    TestScene scene;
    make_icosphere(2).append_triangles(scene.triangles);
    const std::vector<Ray> rays = {
        {{0x1.2cf232p-1f, 0x1.605a9p-1f, -0x1.b3888p-2f},
         {-0x1.3cp+2f, -0x1.fff118p+122f, -0x1.4p+2f},
         -0x1.34p+2f,
         1},
        {{0x1.0d2cap-1f, 0, -0x1.b3888p-1f}, {-0x1.34p+2f, -0x1.34p+2f, -0x1.4p+2f}, -0x1.ep-1f, 1},
        {{-0x1.37ec46p-3f, 0x1.ea2768p-1f, 0x1.f8b3bp-3f},
         {-0x1.18p+114f, -0x1.34p+2f, -0x1.3cp+2f},
         -0x1.4p+2f,
         kInfinity},
        {{0.5f, 0.25f, 0.125f}, {-0x1p-70f, -1, -0x1p-62f}, -2, 2},
        {{-0.25f, 0.5f, 0.125f}, {-1, -0x1p-100f, -0x1p-60f}, -2, 2},
    };
    const std::vector<Hit> expected = trace("brute", scene.geometry(), {}, rays);
    const std::unique_ptr<Accel> brute = make_accel("brute");
    brute->build(scene.geometry(), {});
    std::vector<std::uint8_t> expected_occluded(rays.size());
    brute->occluded(rays, expected_occluded);
    ASSERT_EQ(expected_occluded, (std::vector<std::uint8_t>{1, 1, 0, 1, 1}));
    for (const char* name : {"embree", "embree8", "embree16", "embree_stream"}) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(scene.geometry(), {});
        std::vector<std::uint8_t> occluded(rays.size());
        accel->occluded(rays, occluded);
        EXPECT_EQ(occluded, expected_occluded) << name;
        std::vector<Hit> hits(rays.size());
        accel->intersect(rays, hits);
        for (std::size_t i = 0; i < rays.size(); ++i) {
            ASSERT_EQ(hits[i].hit(), expected[i].hit()) << name << " ray " << i;
            if (expected[i].hit()) {
                EXPECT_NEAR(hits[i].t, expected[i].t, 1e-5f) << name << " ray " << i;
            }
        }
    }
}

// embree.quality selects Embree's build: MEDIUM answers as HIGH (the same rays, within Embree's rounding),
// and any other value is refused with the key named.
TEST(Embree, QualityOptionSelectsTheBuild) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    const TestScene scene = mixed_scene();
    const testing::RaySet set = testing::random_rays(scene.geometry().bounds(), 4000, 13);
    BuildOptions medium;
    set_build_option(medium, "embree.quality=medium");
    EXPECT_EQ(build_option_value(medium, "embree.quality"), "medium");
    const std::vector<Hit> high_hits = trace("embree16", scene.geometry(), {}, set.rays);
    const std::vector<Hit> medium_hits = trace("embree16", scene.geometry(), medium, set.rays);
    const float scale = length(scene.geometry().bounds().extent());
    std::size_t hits = 0;
    for (std::size_t i = 0; i < set.rays.size(); ++i) {
        ASSERT_EQ(high_hits[i].hit(), medium_hits[i].hit()) << "ray " << i;
        if (!high_hits[i].hit()) continue;
        ++hits;
        ASSERT_NEAR(high_hits[i].t, medium_hits[i].t, 1e-5f * (high_hits[i].t + scale)) << "ray " << i;
    }
    EXPECT_GT(hits, 400u);
    try {
        set_build_option(medium, "embree.quality=best");
        ADD_FAILURE() << "embree.quality=best was accepted";
    } catch (const std::invalid_argument& error) {
        EXPECT_NE(std::string(error.what()).find("embree.quality"), std::string::npos) << error.what();
    }
}

// Embree's refit quality through Accel::update, and its other qualities (which rebuild on commit): after each
// move of the vertices, the answers of brute force on the moved scene, within Embree's rounding.
TEST(Embree, UpdatesFollowMovedTriangles) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    const TestScene rest = mixed_scene();
    TestScene moved = rest;
    const float scale = length(rest.geometry().bounds().extent());
    for (const char* quality : {"refit", "high"}) {
        BuildOptions options = build_options(TriangleTest::Watertight);
        set_build_option(options, std::string("embree.quality=") + quality);
        const std::unique_ptr<Accel> accel = make_accel("embree16");
        accel->build(rest.geometry(), options);
        EXPECT_EQ(accel->update_method(),
                  quality == std::string("refit") ? UpdateMethod::Refit : UpdateMethod::Rebuild);
        for (int step = 1; step <= 3; ++step) {
            for (std::size_t i = 0; i < rest.triangles.size(); ++i) {
                for (auto [from, to] : {std::pair{&rest.triangles[i].v0, &moved.triangles[i].v0},
                                        {&rest.triangles[i].v1, &moved.triangles[i].v1},
                                        {&rest.triangles[i].v2, &moved.triangles[i].v2}})
                    *to =
                        *from + Vec3f(0.0f, 0.3f * std::sin(2.0f * from->x + static_cast<float>(step)), 0.0f);
            }
            EXPECT_EQ(accel->update(moved.geometry()).method, accel->update_method());
            const testing::RaySet set = testing::random_rays(moved.geometry().bounds(), 4000, 20 + step);
            const std::vector<Hit> expected =
                trace("brute", moved.geometry(), build_options(TriangleTest::Watertight), set.rays);
            std::vector<Hit> actual(set.rays.size());
            accel->intersect(set.rays, actual);
            std::size_t mismatches = 0, hits = 0;
            for (std::size_t i = 0; i < set.rays.size(); ++i) {
                hits += expected[i].hit() ? 1 : 0;
                mismatches += expected[i].hit() == actual[i].hit() &&
                                      (!expected[i].hit() || std::fabs(expected[i].t - actual[i].t) <=
                                                                 1e-5f * (std::fabs(expected[i].t) + scale))
                                  ? 0
                                  : 1;
            }
            EXPECT_EQ(mismatches, 0u) << quality << ", step " << step;
            EXPECT_GT(hits, 400u) << quality << ", step " << step;
        }
    }
}

}  // namespace
}  // namespace lancer
