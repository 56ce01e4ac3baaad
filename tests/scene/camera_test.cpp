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

// tile_rays makes 64 rays at once in SIMD lanes: they must be generate's, bit for bit, at the pixels of
// tile_column and tile_row, for square and stretched images and tiles anywhere in them; a lane whose pixel
// lies outside the image gets an invalid ray.
TEST(PinholeCamera, TileRaysAreGeneratesRaysBitForBit) {
    for (const auto& [width, height] : {std::pair{1024, 1024}, std::pair{640, 360}, std::pair{12, 100}}) {
        const PinholeCamera pinhole(canonical_view({{-1, -2, 0.5f}, {3, 1, 2}}, width, height));
        for (const auto& [x0, y0] : {std::pair{0, 0}, std::pair{4, 8}, std::pair{width - 8, height - 8},
                                     std::pair{width - 5, height - 3}}) {
            RayPacket packet;
            pinhole.tile_rays(x0, y0, packet);
            ASSERT_EQ(packet.size, RayPacket::kMaxSize);
            for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
                const int i = x0 + PinholeCamera::tile_column(lane), j = y0 + PinholeCamera::tile_row(lane);
                const Ray ray = packet.ray(lane);
                if (i >= width || j >= height) {
                    EXPECT_FALSE(is_valid(ray)) << "lane " << lane << " outside the image";
                    continue;
                }
                const Ray expected =
                    pinhole.generate(static_cast<float>(i) + 0.5f, static_cast<float>(j) + 0.5f);
                EXPECT_EQ(std::memcmp(&ray, &expected, sizeof(Ray)), 0)
                    << width << "x" << height << " tile (" << x0 << ", " << y0 << ") lane " << lane;
            }
        }
    }
}

// The lane order: every pixel of the tile once, every 16 lanes a 4x4 block and every 8 a 4x2 one.
TEST(PinholeCamera, TileLanesCoverTheTileInBlocks) {
    std::array<int, 64> seen{};
    for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
        const int column = PinholeCamera::tile_column(lane), row = PinholeCamera::tile_row(lane);
        ASSERT_TRUE(column >= 0 && column < 8 && row >= 0 && row < 8);
        ++seen[static_cast<std::size_t>(8 * row + column)];
        const int first = lane - lane % 8;  // the 4x2 block's first lane
        EXPECT_EQ(column - column % 4, PinholeCamera::tile_column(first));
        EXPECT_EQ(row - row % 2, PinholeCamera::tile_row(first));
        EXPECT_EQ(column % 4 + 4 * (row % 2), lane % 8);
    }
    for (const int count : seen)
        EXPECT_EQ(count, 1);
}

}  // namespace
}  // namespace lancer
