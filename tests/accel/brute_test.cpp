// The oracle itself: analytic answers, the tie rule, occlusion against closest hit, the ray contract.
#include "accel/brute.hpp"

#include <gtest/gtest.h>

#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"

namespace lancer {
namespace {

// Ten unit squares (two triangles each) stacked at z = 0, 1, ..., 9; triangle 2k and 2k+1 at z = k.
std::vector<Triangle> stacked_squares() {
    std::vector<Triangle> triangles;
    for (int k = 0; k < 10; ++k) {
        const float z = static_cast<float>(k);
        triangles.push_back({{0, 0, z}, {1, 0, z}, {1, 1, z}});
        triangles.push_back({{0, 0, z}, {1, 1, z}, {0, 1, z}});
    }
    return triangles;
}

std::vector<Hit> intersect_all(const Accel& accel, std::span<const Ray> rays) {
    std::vector<Hit> hits(rays.size());
    accel.intersect(rays, hits);
    return hits;
}

TEST(Brute, FindsTheClosestOfStackedSquares) {
    const std::vector<Triangle> triangles = stacked_squares();
    BruteAccel brute;
    brute.build({triangles, {}}, {});
    const std::vector<Ray> rays = {
        {{0.7f, 0.2f, 20.0f}, {0, 0, -1}, 0.0f, kInfinity},   // from above: top square
        {{0.2f, 0.7f, -5.0f}, {0, 0, 2}, 0.0f, kInfinity},    // from below: bottom
        {{0.7f, 0.2f, 4.5f}, {0, 0, -1}, 0.0f, kInfinity},    // from between
        {{0.7f, 0.2f, 20.0f}, {0, 0, -1}, 12.5f, kInfinity},  // tnear skips 9 and 8
        {{2.0f, 2.0f, 20.0f}, {0, 0, -1}, 0.0f, kInfinity}};  // beside: miss
    const std::vector<Hit> hits = intersect_all(brute, rays);
    EXPECT_EQ(hits[0].prim, 18);
    EXPECT_FLOAT_EQ(hits[0].t, 11.0f);
    EXPECT_EQ(hits[1].prim, 1);
    EXPECT_FLOAT_EQ(hits[1].t, 2.5f);
    EXPECT_EQ(hits[2].prim, 8);
    EXPECT_FLOAT_EQ(hits[2].t, 0.5f);
    EXPECT_EQ(hits[3].prim, 14);
    EXPECT_FLOAT_EQ(hits[3].t, 13.0f);
    EXPECT_FALSE(hits[4].hit());
    EXPECT_EQ(hits[4].t, kInfinity);
}

TEST(Brute, CoincidentTrianglesTieToTheSmallestIndex) {
    const Triangle tri{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    const std::vector<Triangle> triangles = {{{5, 5, 5}, {6, 5, 5}, {5, 6, 5}}, tri, tri, tri};
    BruteAccel brute;
    brute.build({triangles, {}}, {});
    const Ray ray{{0.2f, 0.2f, 1.0f}, {0, 0, -1}, 0.0f, kInfinity};
    EXPECT_EQ(intersect_all(brute, {&ray, 1})[0].prim, 1);
}

TEST(Brute, SpheresAreNumberedAfterTriangles) {
    const std::vector<Triangle> triangles = {{{-1, -1, -5}, {1, -1, -5}, {0, 1, -5}}};
    const std::vector<Sphere> spheres = {{{10, 0, 0}, 1.0f, 0}, {{0, 0, 0}, 1.0f, 0}};
    BruteAccel brute;
    brute.build({triangles, spheres}, {});
    const Ray ray{{0, 0, 5}, {0, 0, -1}, 0.0f, kInfinity};
    const Hit hit = intersect_all(brute, {&ray, 1})[0];
    EXPECT_EQ(hit.prim, 2);  // the second sphere, in front of the triangle
    EXPECT_FLOAT_EQ(hit.t, 4.0f);
}

TEST(Brute, HitsLieOnTheirTriangleInsideTheRayInterval) {
    const TriangleMesh mesh = make_icosphere(2);
    const std::vector<Triangle> triangles = mesh.triangles();
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        BruteAccel brute;
        brute.build({triangles, {}}, build_options(test));
        const Box3f bounds = Geometry{triangles, {}}.bounds();
        std::size_t checked = 0;
        for (const auto& set :
             {testing::random_rays(bounds, 2000, 1), testing::clipped_rays(bounds, 2000, 2)}) {
            const std::vector<Hit> hits = intersect_all(brute, set.rays);
            for (std::size_t i = 0; i < hits.size(); ++i) {
                if (!hits[i].hit()) continue;
                const Ray& ray = set.rays[i];
                ASSERT_GE(hits[i].t, ray.tnear);
                ASSERT_LE(hits[i].t, ray.tfar);
                const Triangle& tri = triangles[static_cast<std::size_t>(hits[i].prim)];
                const Vec3f on_triangle =
                    (1.0f - hits[i].u - hits[i].v) * tri.v0 + hits[i].u * tri.v1 + hits[i].v * tri.v2;
                const Vec3f on_ray = ray.origin + hits[i].t * ray.direction;
                ASSERT_LT(length(on_triangle - on_ray), 1e-5f) << set.name << " ray " << i;
                ++checked;
            }
        }
        EXPECT_GT(checked, 1000u);
    }
}

TEST(Brute, OcclusionAgreesWithClosestHit) {
    const TriangleMesh mesh = make_icosphere(2);
    const std::vector<Triangle> triangles = mesh.triangles();
    const std::vector<Sphere> spheres = {{{0.5f, 0.5f, 0.5f}, 0.7f, 0}, {{-2, 0, 0}, 0.3f, 0}};
    BruteAccel brute;
    brute.build({triangles, spheres}, {});
    const Box3f bounds = Geometry{triangles, spheres}.bounds();
    for (const auto& set :
         {testing::random_rays(bounds, 3000, 3), testing::vertex_and_edge_rays(triangles, 3000, 4),
          testing::axis_parallel_rays(bounds, 3000, 5), testing::clipped_rays(bounds, 3000, 6),
          testing::hostile_rays(bounds)}) {
        const std::vector<Hit> hits = intersect_all(brute, set.rays);
        std::vector<std::uint8_t> occluded(set.rays.size());
        brute.occluded(set.rays, occluded);
        for (std::size_t i = 0; i < hits.size(); ++i) {
            ASSERT_EQ(hits[i].hit(), occluded[i] != 0) << set.name << " ray " << i;
        }
    }
}

TEST(Brute, InvalidRaysMissAndValidHostileRaysAreAnswered) {
    const std::vector<Triangle> triangles = stacked_squares();
    BruteAccel brute;
    brute.build({triangles, {}}, {});
    const testing::RaySet hostile = testing::hostile_rays(Geometry{triangles, {}}.bounds());
    const std::vector<Hit> hits = intersect_all(brute, hostile.rays);
    for (std::size_t i = 0; i < hits.size(); ++i) {
        if (!is_valid(hostile.rays[i])) {
            EXPECT_FALSE(hits[i].hit()) << "invalid ray " << i;
            EXPECT_EQ(hits[i].t, kInfinity);
        }
    }
    EXPECT_TRUE(hits[0].hit());  // the one ordinary ray of the set, straight down onto the top square
}

TEST(Brute, EmptyGeometryMissesEverything) {
    BruteAccel brute;
    brute.build({}, {});
    const testing::RaySet set = testing::random_rays({{-1, -1, -1}, {1, 1, 1}}, 100, 9);
    for (const Hit& hit : intersect_all(brute, set.rays))
        EXPECT_FALSE(hit.hit());
    EXPECT_EQ(brute.stats().primitives, 0u);
}

TEST(Brute, CountersCountRaysAndPrimitiveTests) {
    const std::vector<Triangle> triangles = stacked_squares();
    BruteAccel brute;
    brute.build({triangles, {}}, {});
    const std::vector<Ray> rays = {{{0.7f, 0.2f, 20.0f}, {0, 0, -1}, 0.0f, kInfinity},
                                   {{0.7f, 0.2f, 20.0f}, {0, 0, 0}, 0.0f, kInfinity}};  // invalid: not tested
    std::vector<Hit> hits(rays.size());
    TraversalCounters counters;
    brute.intersect(rays, hits, &counters);
    EXPECT_EQ(counters.rays, 2u);
    EXPECT_EQ(counters.prims_tested, 20u);
}

TEST(Registry, UnknownNameListsTheKnownStructures) {
    EXPECT_EQ(make_accel("brute")->name(), "brute");
    try {
        (void)make_accel("nope");
        FAIL() << "expected std::invalid_argument";
    } catch (const std::invalid_argument& error) {
        EXPECT_NE(std::string(error.what()).find("brute"), std::string::npos);
        EXPECT_NE(std::string(error.what()).find("nope"), std::string::npos);
    }
}

}  // namespace
}  // namespace lancer
