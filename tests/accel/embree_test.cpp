// Embree behind lancer's interface: the same answers as brute force on random rays (within Embree's own
// rounding), the global primitive numbering, the ray contract, and packets equal to single rays.
#include <gtest/gtest.h>

#include <cmath>

#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "ray_sets.hpp"
#include "test_scenes.hpp"

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
    for (const TriangleMesh& mesh : {make_icosphere(3), make_torus_knot(300, 10)}) {
        for (std::size_t i = 0; i < mesh.triangle_count(); ++i)
            scene.triangles.push_back(mesh.triangle(i));
    }
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
    const testing::RaySet set = testing::random_rays(scene.geometry().bounds(), 20000, 7);
    const float scale = length(scene.geometry().bounds().extent());
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const std::vector<Hit> expected = trace("brute", scene.geometry(), build_options(test), set.rays);
        const std::vector<Hit> actual = trace("embree", scene.geometry(), build_options(test), set.rays);
        std::size_t mismatches = 0, hits = 0;
        for (std::size_t i = 0; i < set.rays.size(); ++i) {
            hits += expected[i].hit() ? 1 : 0;
            // Embree's sphere and triangle t carry an absolute rounding error of a few ulps of the scene's
            // size (it does not use our kernels), hence a tolerance scaled by the scene, not by t alone.
            const bool same = expected[i].hit() == actual[i].hit() &&
                              (!expected[i].hit() || std::fabs(expected[i].t - actual[i].t) <=
                                                         1e-5f * (std::fabs(expected[i].t) + scale));
            if (!same && mismatches++ < 3) {
                ADD_FAILURE() << "ray " << i << ": brute prim " << expected[i].prim << " t " << expected[i].t
                              << ", embree prim " << actual[i].prim << " t " << actual[i].t;
            }
        }
        std::printf("embree vs brute (%s): %zu random rays, %zu hits, %zu mismatches\n",
                    test == TriangleTest::Watertight ? "watertight/robust" : "moller/default",
                    set.rays.size(), hits, mismatches);
        EXPECT_EQ(mismatches, 0u);
        EXPECT_GT(hits, 2000u);
    }
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

TEST(Embree, PacketsAnswerLikeSingleRays) {
    if (!has_embree()) GTEST_SKIP() << "built without Embree";
    const TestScene scene = mixed_scene();
    testing::RaySet set = testing::random_rays(scene.geometry().bounds(), 5003, 9);  // not a multiple of 16
    for (const Ray& hostile : testing::hostile_rays(scene.geometry().bounds()).rays)
        set.rays.push_back(hostile);
    const std::vector<Hit> single = trace("embree", scene.geometry(), {}, set.rays);
    const float scale = length(scene.geometry().bounds().extent());
    for (EmbreePacket packet : {EmbreePacket::Packet8, EmbreePacket::Packet16}) {
        BuildOptions options;
        options.embree_packet = packet;
        const std::vector<Hit> packed = trace("embree", scene.geometry(), options, set.rays);
        for (std::size_t i = 0; i < set.rays.size(); ++i) {
            ASSERT_EQ(single[i].prim, packed[i].prim) << "ray " << i;
            if (single[i].hit()) {
                // Embree's packet kernels round differently from its single-ray ones: the same scene-scaled
                // tolerance as against brute force.
                ASSERT_NEAR(single[i].t, packed[i].t, 1e-5f * (single[i].t + scale)) << "ray " << i;
            }
        }
    }
}

}  // namespace
}  // namespace lancer
