// The pinhole camera reproduces shared/bench/VIEWS.md formula by formula.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <utility>

#include "lancer/camera.hpp"

namespace lancer {
namespace {

TEST(CanonicalView, EyeDistanceAndFrameFollowViewsMd) {
    const Box3f bounds{{-1, -2, -3}, {3, 2, 1}};
    const Camera camera = canonical_view(bounds, 64, 32);
    const float r = std::sqrt(16.0f + 16.0f + 16.0f) / 2.0f;
    const float d = 1.05f * r / std::sin(std::numbers::pi_v<float> / 8.0f);
    EXPECT_FLOAT_EQ(camera.eye.x, 1.0f);
    EXPECT_FLOAT_EQ(camera.eye.y, 0.0f);
    EXPECT_FLOAT_EQ(camera.eye.z, -1.0f + d);
    EXPECT_EQ(camera.look_at, Vec3f(1.0f, 0.0f, -1.0f));
    EXPECT_EQ(camera.width, 64);
    EXPECT_EQ(camera.height, 32);
}

TEST(PinholeCamera, PixelDirectionsMatchTheFormula) {
    const Camera camera = canonical_view({{-1, -1, -1}, {1, 1, 1}}, 8, 4);
    const PinholeCamera pinhole(camera);
    const float tan_half = std::tan(std::numbers::pi_v<float> / 8.0f);
    for (int j = 0; j < 4; ++j) {
        for (int i = 0; i < 8; ++i) {
            const Ray ray = pinhole.generate(static_cast<float>(i) + 0.5f, static_cast<float>(j) + 0.5f);
            // Looking down -z with y up: f = (0, 0, -1), x = f cross up = (1, 0, 0), y = (0, 1, 0).
            const float u = (2.0f * (static_cast<float>(i) + 0.5f) / 8.0f - 1.0f) * tan_half * 2.0f;
            const float v = (1.0f - 2.0f * (static_cast<float>(j) + 0.5f) / 4.0f) * tan_half;
            const Vec3f expected = normalize(Vec3f(u, v, -1.0f));
            EXPECT_NEAR(ray.direction.x, expected.x, 1e-6f);
            EXPECT_NEAR(ray.direction.y, expected.y, 1e-6f);
            EXPECT_NEAR(ray.direction.z, expected.z, 1e-6f);
            EXPECT_EQ(ray.origin, camera.eye);
            EXPECT_EQ(ray.tnear, 0.0f);
            EXPECT_EQ(ray.tfar, kInfinity);
        }
    }
}

TEST(PinholeCamera, FilmEdgesSpanTheVerticalFieldOfView) {
    Camera camera;
    camera.eye = {0, 0, 0};
    camera.look_at = {0, 0, -1};
    camera.vertical_fov_degrees = 60.0f;
    camera.width = camera.height = 100;
    const PinholeCamera pinhole(camera);
    const Ray top = pinhole.generate(50.0f, 0.0f);
    EXPECT_NEAR(std::atan2(top.direction.y, -top.direction.z), std::numbers::pi_v<float> / 6.0f, 1e-6f);
}

// block_rays makes 16 rays at once in SIMD lanes: they must be generate's, bit for bit, in row order, for
// square and stretched images and blocks anywhere in them.
TEST(PinholeCamera, BlockRaysAreGeneratesRaysBitForBit) {
    for (const auto& [width, height] : {std::pair{1024, 1024}, std::pair{640, 360}, std::pair{12, 100}}) {
        const PinholeCamera pinhole(canonical_view({{-1, -2, 0.5f}, {3, 1, 2}}, width, height));
        for (const auto& [x0, y0] : {std::pair{0, 0}, std::pair{4, 8}, std::pair{width - 4, height - 4}}) {
            std::array<Ray, 16> block;
            pinhole.block_rays(x0, y0, block);
            for (int k = 0; k < 16; ++k) {
                const Ray expected = pinhole.generate(static_cast<float>(x0 + k % 4) + 0.5f,
                                                      static_cast<float>(y0 + k / 4) + 0.5f);
                const Ray& ray = block[static_cast<std::size_t>(k)];
                EXPECT_EQ(std::memcmp(&ray, &expected, sizeof(Ray)), 0)
                    << width << "x" << height << " block (" << x0 << ", " << y0 << ") ray " << k;
            }
        }
    }
}

}  // namespace
}  // namespace lancer
