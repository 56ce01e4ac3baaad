// The pinhole camera reproduces shared/bench/VIEWS.md formula by formula.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

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

}  // namespace
}  // namespace lancer
