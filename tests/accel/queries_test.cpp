// GeometryQueries::all_hits against every primitive tested one by one: the same hits, each once, in order.
#include "lancer/queries.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "accel/primitive_test.hpp"
#include "ray_sets.hpp"
#include "test_scenes.hpp"

namespace lancer {
namespace {

// Every primitive the ray hits within [tnear, tfar], tested one at a time, sorted as all_hits promises.
std::vector<Hit> every_hit(const Geometry& geometry, const Ray& ray, TriangleTest test) {
    std::vector<Hit> hits;
    if (!is_valid(ray)) return hits;
    dispatch_policies(test, false, [&]<class TriangleTestT, bool>() {
        const PreparedRay<TriangleTestT> prepared(ray);
        for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
            Hit hit;
            if (intersect_primitive(geometry, prim, prepared, hit)) hits.push_back(hit);
        }
    });
    std::sort(hits.begin(), hits.end(),
              [](const Hit& a, const Hit& b) { return a.t < b.t || (a.t == b.t && a.prim < b.prim); });
    return hits;
}

TEST(GeometryQueries, AllHitsAreEveryPrimitivesHitInOrder) {
    const std::vector<Triangle> triangles = testing::knot_triangles(96);
    const Geometry geometry{triangles, {}};
    std::size_t rays_with_several = 0, checked = 0;
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const GeometryQueries queries(geometry, test);
        const Box3f bounds = geometry.bounds();
        for (const testing::RaySet& set :
             {testing::random_rays(bounds, 3000, 31), testing::vertex_and_edge_rays(triangles, 2000, 32),
              testing::axis_parallel_rays(bounds, 1000, 33), testing::clipped_rays(bounds, 1000, 34)}) {
            for (const Ray& ray : set.rays) {
                std::vector<Hit> hits;
                queries.all_hits(ray, hits);
                const std::vector<Hit> expected = every_hit(geometry, ray, test);
                ASSERT_EQ(hits.size(), expected.size()) << set.name;
                for (std::size_t i = 0; i < hits.size(); ++i) {
                    ASSERT_EQ(hits[i].prim, expected[i].prim) << set.name;
                    ASSERT_EQ(hits[i].t, expected[i].t) << set.name;
                    ASSERT_EQ(hits[i].u, expected[i].u) << set.name;
                }
                rays_with_several += hits.size() > 1 ? 1 : 0;
                ++checked;
            }
        }
    }
    EXPECT_EQ(checked, 14000u);
    EXPECT_GT(rays_with_several, 1000u);  // the knot is crossed several times by most rays that reach it
}

TEST(GeometryQueries, AppendsAndIgnoresInvalidRays) {
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const GeometryQueries queries({triangles, {}}, TriangleTest::Watertight);
    std::vector<Hit> hits(1);  // kept: all_hits appends
    queries.all_hits({{0.2f, 0.2f, 1}, {0, 0, -1}, 0.0f, kInfinity}, hits);
    ASSERT_EQ(hits.size(), 2u);
    EXPECT_EQ(hits[1].prim, 0);
    EXPECT_EQ(hits[1].t, 1.0f);
    queries.all_hits({{0.2f, 0.2f, 1}, {0, 0, 0}, 0.0f, kInfinity}, hits);  // zero direction: invalid
    EXPECT_EQ(hits.size(), 2u);
}

}  // namespace
}  // namespace lancer
