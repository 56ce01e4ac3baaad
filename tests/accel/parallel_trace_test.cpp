// intersect_parallel and occluded_parallel (lancer/accel.hpp): the answers of one call, whatever the threads,
// on a batch of several tasks.
#include <gtest/gtest.h>

#include <cstring>
#include <stdexcept>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"

namespace lancer {
namespace {

TEST(ParallelTrace, GivesTheAnswersOfOneCallWhateverTheThreads) {
    const std::vector<Triangle> triangles = make_torus_knot(128, 12).triangles();
    const Geometry geometry{triangles, {}};
    const std::unique_ptr<Accel> accel = make_accel("bvh8");
    accel->build(geometry, build_options(TriangleTest::Watertight));
    // Three tasks and a part, with a few invalid rays among them.
    std::vector<Ray> rays = testing::random_rays(geometry.bounds(), 3 * 4096 + 123, 41).rays;
    rays[5000].direction = {0.0f, 0.0f, 0.0f};
    rays[9000].tnear = 2.0f, rays[9000].tfar = 1.0f;
    std::vector<Hit> expected(rays.size());
    std::vector<std::uint8_t> expected_occluded(rays.size());
    accel->intersect(rays, expected);
    accel->occluded(rays, expected_occluded);
    std::size_t hits = 0;
    for (const Hit& hit : expected)
        hits += hit.hit() ? 1 : 0;
    ASSERT_GT(hits, rays.size() / 20);
    for (const int threads : {0, 1, 2}) {
        std::vector<Hit> parallel_hits(rays.size(), Hit{-1.0f, 7, 0.5f, 0.5f});
        std::vector<std::uint8_t> parallel_occluded(rays.size(), 2);
        intersect_parallel(*accel, rays, parallel_hits, threads);
        occluded_parallel(*accel, rays, parallel_occluded, threads);
        EXPECT_EQ(std::memcmp(parallel_hits.data(), expected.data(), expected.size() * sizeof(Hit)), 0)
            << threads;
        EXPECT_EQ(parallel_occluded, expected_occluded) << threads;
    }
    std::vector<Hit> short_hits(rays.size() - 1);
    EXPECT_THROW(intersect_parallel(*accel, rays, short_hits), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
