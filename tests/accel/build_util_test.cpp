// The build helpers: overlap never misses a touching primitive, clipping gives the exact clipped box.
#include "accel/build_util.hpp"

#include <gtest/gtest.h>

#include <random>

namespace lancer {
namespace {

TEST(BuildUtil, OverlapOfTrianglesInsideAcrossTouchingAndApart) {
    const Box3f box{{0, 0, 0}, {1, 1, 1}};
    const std::vector<Triangle> triangles = {
        {{0.2f, 0.2f, 0.2f}, {0.8f, 0.2f, 0.2f}, {0.2f, 0.8f, 0.2f}},  // inside
        {{-1, 0.5f, -1}, {2, 0.5f, -1}, {0.5f, 0.5f, 2}},              // across, no vertex inside
        {{1, 0, 0}, {2, 0, 0}, {2, 1, 0}},                             // touches the box at one vertex
        {{1.0f, 0.2f, 0.2f}, {1.0f, 0.8f, 0.2f}, {1.0f, 0.2f, 0.8f}},  // lies in the face x = 1
        {{2, 2, 2}, {3, 2, 2}, {2, 3, 2}},                             // apart
        {{1.5f, -1, 0.5f}, {3, 0.5f, 0.5f}, {1.5f, 3, 0.5f}},          // its bounds overlap, it does not
    };
    const Geometry geometry{triangles, {}};
    EXPECT_TRUE(primitive_overlaps_box(geometry, 0, box));
    EXPECT_TRUE(primitive_overlaps_box(geometry, 1, box));
    EXPECT_TRUE(primitive_overlaps_box(geometry, 2, box));
    EXPECT_TRUE(primitive_overlaps_box(geometry, 3, box));
    EXPECT_FALSE(primitive_overlaps_box(geometry, 4, box));
    EXPECT_FALSE(primitive_overlaps_box(geometry, 5, box));
}

TEST(BuildUtil, SphereOverlap) {
    const std::vector<Sphere> spheres = {{{1.5f, 0.5f, 0.5f}, 0.6f, 0}, {{1.5f, 1.5f, 1.5f}, 0.8f, 0}};
    const Geometry geometry{{}, spheres};
    EXPECT_TRUE(primitive_overlaps_box(geometry, 0, {{0, 0, 0}, {1, 1, 1}}));
    EXPECT_FALSE(primitive_overlaps_box(geometry, 1, {{0, 0, 0}, {1, 1, 1}}));  // bounds overlap, sphere not
}

TEST(BuildUtil, ClippedBoundsOfACrossingTriangle) {
    const std::vector<Triangle> triangles = {{{-1, 0.5f, -1}, {2, 0.5f, -1}, {0.5f, 0.5f, 2}}};
    const Box3f clipped = clipped_primitive_bounds({triangles, {}}, 0, {{0, 0, 0}, {1, 1, 1}});
    EXPECT_FLOAT_EQ(clipped.lo.y, 0.5f);
    EXPECT_FLOAT_EQ(clipped.hi.y, 0.5f);
    EXPECT_FLOAT_EQ(clipped.lo.x, 0.0f);
    EXPECT_FLOAT_EQ(clipped.hi.x, 1.0f);
    EXPECT_FLOAT_EQ(clipped.lo.z, 0.0f);
    EXPECT_FLOAT_EQ(clipped.hi.z, 1.0f);
}

TEST(BuildUtil, ClippedBoundsAreInsideBothBoxesAndContainSampledPoints) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> coordinate(-1.0f, 2.0f), unit(0.0f, 1.0f);
    auto point = [&] { return Vec3f(coordinate(rng), coordinate(rng), coordinate(rng)); };
    const Box3f box{{0, 0, 0}, {1, 1, 1}};
    for (int trial = 0; trial < 2000; ++trial) {
        const std::vector<Triangle> triangles = {{point(), point(), point()}};
        const Box3f clipped = clipped_primitive_bounds({triangles, {}}, 0, box);
        // Points of the triangle inside the box must lie in the clipped bounds.
        for (int sample = 0; sample < 50; ++sample) {
            float a = unit(rng), b = unit(rng);
            if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
            const Triangle& t = triangles[0];
            const Vec3f p = t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0);
            if (!box.contains(p)) continue;
            ASSERT_FALSE(clipped.empty());
            ASSERT_TRUE(grown_for_overlap(clipped).contains(p)) << "trial " << trial;
            ASSERT_TRUE(primitive_overlaps_box({triangles, {}}, 0, box));
        }
        if (!clipped.empty()) {
            EXPECT_TRUE(box.contains(clipped.lo) && box.contains(clipped.hi));
            EXPECT_TRUE(grown_for_overlap(triangles[0].bounds()).contains(clipped.lo));
            EXPECT_TRUE(grown_for_overlap(triangles[0].bounds()).contains(clipped.hi));
        }
    }
}

}  // namespace
}  // namespace lancer
