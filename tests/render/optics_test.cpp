// Reflection, Snell-Descartes refraction and its critical angle, Fresnel, secondary-ray offsets, pixel
// samples: src/render/optics.hpp against values worked out by hand.
#include "render/optics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <set>

#include "print_vec.hpp"

namespace lancer {
namespace {

constexpr float kDegree = std::numbers::pi_v<float> / 180.0f;

// A unit direction arriving at the plane z = 0 from above at `degrees` from the normal +z.
Vec3f incoming(float degrees) {
    return {std::sin(degrees * kDegree), 0.0f, -std::cos(degrees * kDegree)};
}

TEST(Optics, ReflectionMirrorsTheNormalComponent) {
    const Vec3f r = reflect(incoming(30.0f), {0.0f, 0.0f, 1.0f});
    EXPECT_NEAR(r.x, std::sin(30.0f * kDegree), 1e-7f);
    EXPECT_NEAR(r.z, std::cos(30.0f * kDegree), 1e-7f);
    EXPECT_EQ(r.y, 0.0f);
}

TEST(Optics, RefractionFollowsSnellDescartes) {
    for (const float degrees : {0.0f, 10.0f, 45.0f, 80.0f}) {
        SCOPED_TRACE(degrees);
        const float eta = 1.0f / 1.5f;  // air into glass
        const std::optional<Vec3f> t = refract(incoming(degrees), {0.0f, 0.0f, 1.0f}, eta);
        ASSERT_TRUE(t.has_value());
        EXPECT_NEAR(length(*t), 1.0f, 1e-6f);
        EXPECT_LT(t->z, 0.0f);  // through the surface
        // n_i sin(theta_i) = n_t sin(theta_t)
        EXPECT_NEAR(1.0f * std::sin(degrees * kDegree), 1.5f * t->x, 1e-6f);
    }
}

// From glass (1.5) into air the critical angle is asin(1 / 1.5) = 41.81 degrees.
TEST(Optics, TotalInternalReflectionPastTheCriticalAngleAndNotBefore) {
    const float critical = std::asin(1.0f / 1.5f) / kDegree;
    const Vec3f normal{0.0f, 0.0f, 1.0f};
    EXPECT_TRUE(refract(incoming(critical - 0.01f), normal, 1.5f).has_value());
    EXPECT_FALSE(refract(incoming(critical + 0.01f), normal, 1.5f).has_value());
    EXPECT_FALSE(refract(incoming(89.0f), normal, 1.5f).has_value());
    // Just before, the refracted ray grazes the surface.
    const Vec3f grazing = *refract(incoming(critical - 0.01f), normal, 1.5f);
    EXPECT_GT(grazing.x, 0.99f);
    // Entering the denser medium never reflects totally.
    for (float degrees = 0.0f; degrees < 90.0f; degrees += 0.5f)
        EXPECT_TRUE(refract(incoming(degrees), normal, 1.0f / 1.5f).has_value()) << degrees;
}

TEST(Optics, FresnelReflectance) {
    // Normal incidence: ((n - 1) / (n + 1))^2 = 0.04 for glass, from either side.
    EXPECT_NEAR(fresnel_dielectric(1.0f, 1.0f / 1.5f), 0.04f, 1e-6f);
    EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-6f);
    // Brewster's angle atan(1.5): r_p = 0, so the mean is r_s^2 / 2.
    const float brewster = std::atan(1.5f);
    const float cos_t = std::cos(std::numbers::pi_v<float> / 2.0f - brewster);
    const float r_s = (std::cos(brewster) - 1.5f * cos_t) / (std::cos(brewster) + 1.5f * cos_t);
    EXPECT_NEAR(fresnel_dielectric(std::cos(brewster), 1.0f / 1.5f), 0.5f * r_s * r_s, 1e-6f);
    EXPECT_EQ(fresnel_dielectric(std::cos(60.0f * kDegree), 1.5f), 1.0f);  // past the critical angle
    EXPECT_NEAR(fresnel_dielectric(0.0f, 1.0f / 1.5f), 1.0f, 1e-6f);       // grazing
    EXPECT_EQ(fresnel_dielectric(0.7f, 1.0f), 0.0f);                       // no interface
}

TEST(Optics, OffsetGrowsWithTheCoordinatesAndFollowsTheNormal) {
    const Vec3f up{0.0f, 1.0f, 0.0f};
    for (const float y : {-3e4f, -1.0f, 0.5f, 7.0f, 1e4f, 3e6f}) {
        SCOPED_TRACE(y);
        const Vec3f p{y, y, -y};
        const Vec3f moved = offset_ray_origin(p, up);
        EXPECT_EQ(moved.x, p.x);  // no normal component along x and z: unchanged
        EXPECT_EQ(moved.z, p.z);
        EXPECT_GT(moved.y, p.y);
        // 256 ulps of y: far more than the few ulps of a computed hit point, far less than the scene.
        EXPECT_NEAR(
            moved.y - p.y,
            256.0f * (std::nextafter(std::fabs(y), std::numeric_limits<float>::infinity()) - std::fabs(y)),
            1e-3f * std::fabs(y));
        EXPECT_EQ(offset_ray_origin(p, -up).y < p.y, true);
    }
    // Near zero, where ulps vanish, a fixed step.
    const Vec3f moved = offset_ray_origin(Vec3f(0.0f), up);
    EXPECT_EQ(moved.y, 1.0f / 65536.0f);
}

TEST(Optics, PixelSamplesAreStratified) {
    EXPECT_EQ(pixel_sample(0, 1).x, 0.5f);
    EXPECT_EQ(pixel_sample(0, 1).y, 0.5f);
    for (const std::uint32_t n : {4u, 16u, 64u}) {
        SCOPED_TRACE(n);
        std::set<int> columns, rows;
        for (std::uint32_t s = 0; s < n; ++s) {
            const PixelSample sample = pixel_sample(s, n);
            ASSERT_GE(sample.x, 0.0f);
            ASSERT_LT(sample.x, 1.0f);
            ASSERT_GE(sample.y, 0.0f);
            ASSERT_LT(sample.y, 1.0f);
            columns.insert(static_cast<int>(sample.x * static_cast<float>(n)));
            rows.insert(static_cast<int>(sample.y * static_cast<float>(n)));
        }
        EXPECT_EQ(columns.size(), n);  // one sample in each column
        EXPECT_EQ(rows.size(), n);     // and in each row
    }
}

}  // namespace
}  // namespace lancer
