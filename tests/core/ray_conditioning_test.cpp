// Rays conditioned before any structure sees them (src/core/ray_conditioning.hpp; docs/numerical-contract.md,
// "Ray conditioning"): far rays moved near the scene keep their line, extreme directions are scaled exactly,
// t maps back, ordinary rays are left alone.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "core/ray_conditioning.hpp"

namespace lancer {
namespace {

const Box3f kScene{{-1.0f, -2.0f, 0.0f}, {3.0f, 2.0f, 1.0f}};  // centre (1, 0, 0.5), sides 4, 4 and 1

// Squared distance from p to the exact line o + t d, in quadruple precision (GCC's and clang's __float128:
// 113 bits, so that the test's own rounding stays below 1e-9 for origins up to 1e24 away).
double squared_distance_to_line(Vec3f p, const Ray& ray) {
    using Quad = __float128;
    const Quad dx = ray.direction.x, dy = ray.direction.y, dz = ray.direction.z;
    const Quad wx = Quad(p.x) - ray.origin.x, wy = Quad(p.y) - ray.origin.y, wz = Quad(p.z) - ray.origin.z;
    const Quad t = (wx * dx + wy * dy + wz * dz) / (dx * dx + dy * dy + dz * dz);
    const Quad ex = wx - t * dx, ey = wy - t * dy, ez = wz - t * dz;
    return static_cast<double>(ex * ex + ey * ey + ez * ez);
}

// Far is measured in the box's largest side (4 here), from its centre, on each axis.
TEST(RayConditioning, OriginsWithin4SidesAreNotFar) {
    const FarOriginFrame frame(kScene);
    EXPECT_FALSE(frame.is_far({1.0f, 0.0f, 0.5f}));
    EXPECT_FALSE(frame.is_far({1.0f + 16.0f, 0.0f, 0.5f}));  // 4 sides from the centre
    EXPECT_TRUE(frame.is_far({std::nextafter(1.0f + 16.0f, kInfinity), 0.0f, 0.5f}));
    EXPECT_FALSE(frame.is_far({1.0f, -16.0f, 0.5f - 16.0f}));
    EXPECT_TRUE(frame.is_far({1.0f, -16.0f, 0.5f - 16.5f}));
    EXPECT_TRUE(frame.is_far({1.0f, 0.0f, -1e30f}));
    EXPECT_FALSE(FarOriginFrame(Box3f{}).is_far({1e30f, 0.0f, 0.0f})) << "an empty scene has nothing far";
}

// From 1e6 to 1e24 away, lines through the point 0 of the scene (d = -o times a power of two, exact: a float
// origin that far cannot aim at another point of a unit scene): the moved origin lies on the exact line, near
// its point nearest to the centre c (the projection of c, since the line passes through 0), and t maps back.
TEST(RayConditioning, MovedRaysKeepTheirLine) {
    const FarOriginFrame frame(kScene);
    const Vec3f centre = kScene.center();
    std::mt19937 random(20261122);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    for (int i = 0; i < 20000; ++i) {
        const float distance = std::pow(10.0f, 6.0f + 18.0f * (unit(random) + 1.0f) / 2.0f);
        const Vec3f away = normalize(Vec3f(unit(random), unit(random), unit(random)));
        Ray ray;
        ray.origin = away * distance;
        ray.direction = -ray.origin * std::ldexp(1.0f, static_cast<int>(10.0f * unit(random)));
        ray.tnear = -5.0f, ray.tfar = 5e3f;
        ASSERT_TRUE(frame.is_far(ray.origin));
        const FarOriginFrame::Moved moved = frame.move_near(ray, ray.tnear, ray.tfar);
        // On the line: what is left is the float rounding of a point near the scene (2^-22 here).
        EXPECT_LT(squared_distance_to_line(moved.ray.origin, ray), 1e-12) << "ray " << i;
        // Near the scene: the rounds stop once the point is no longer far, within 2^-24 of the last distance
        // of the point of the line nearest to the centre.
        EXPECT_FALSE(frame.is_far(moved.ray.origin)) << "ray " << i;
        const Vec3f unit_line = normalize(ray.origin);
        const Vec3f nearest = unit_line * dot(centre, unit_line);
        EXPECT_LT(length(moved.ray.origin - nearest), 0x1p-23f * 32.0f + 0x1p-23f * distance) << "ray " << i;
        EXPECT_EQ(moved.ray.direction, ray.direction);
        // The interval is the same one, rounded outwards.
        EXPECT_LE(double(moved.ray.tnear), double(ray.tnear) - moved.shift);
        EXPECT_GE(double(moved.ray.tfar), double(ray.tfar) - moved.shift);
        // t back in the caller's parametrisation, clamped to [tnear, tfar]; the point 0 is at t = 1.
        const RayConditioning how{moved.shift, 0};
        EXPECT_NEAR(*restore_t(static_cast<float>(1.0 - moved.shift), how, ray), 1.0f, 1e-6f) << "ray " << i;
        EXPECT_EQ(restore_t(-1e30f, how, ray), ray.tnear);
        EXPECT_EQ(restore_t(1e30f, how, ray), ray.tfar);
    }
}

// Fuzz finding 20: an origin at FLT_MAX on the diagonal, along a direction whose scaled length is below 1,
// reaches the scene's point 0 at t' = -2^128 (t = -1 for the caller): the shift passes the float range and
// the interval, clamped to -FLT_MAX by scale_direction, must come from the caller's. The move keeps the
// exact line (the diagonal: all three components of the moved origin are equal), lands near the scene, and
// the point 0 maps back to t = -1.
TEST(RayConditioning, AShiftBeyondTheFloatRangeMovesTheRay) {
    const float float_max = std::numeric_limits<float>::max();
    const std::vector<Ray> rays = {{Vec3f(float_max), Vec3f(float_max), -2.625f, kInfinity}};
    const ConditionedRays conditioned = condition_rays(rays, kScene);
    ASSERT_EQ(conditioned.rays.size(), 1u);
    const Ray& moved = conditioned.rays[0];
    EXPECT_EQ(conditioned.how[0].exponent, 128);
    EXPECT_LT(conditioned.how[0].shift, -double(float_max));
    EXPECT_EQ(moved.origin.x, moved.origin.y);
    EXPECT_EQ(moved.origin.y, moved.origin.z);
    EXPECT_FALSE(FarOriginFrame(kScene).is_far(moved.origin));
    EXPECT_TRUE(is_valid(moved));
    // The point 0 of the line, at t' = -o.x / d.x of the moved ray, lies inside its interval and maps back
    // to the caller's t = -1.
    const float t_at_zero = -moved.origin.x / moved.direction.x;
    EXPECT_GE(t_at_zero, moved.tnear);
    std::vector<Hit> hits = {{t_at_zero, 0, 0, 0}};
    restore_hits(conditioned, rays, hits);
    EXPECT_NEAR(hits[0].t, -1.0f, 1e-6f);

    // A denormal direction from 1e30 away, left unscaled: the nearest point is at t ~ 1e75, a shift beyond
    // the float range too. The ray is moved, and a hit there maps back to no hit (t overflows the float).
    const FarOriginFrame frame(kScene);
    const Ray tiny{{1e30f, 0.0f, 0.0f}, {-0x1p-149f, 0.0f, 0.0f}, 0.0f, kInfinity};
    const FarOriginFrame::Moved moved_tiny = frame.move_near(tiny, tiny.tnear, tiny.tfar);
    EXPECT_FALSE(frame.is_far(moved_tiny.ray.origin));
    EXPECT_EQ(moved_tiny.ray.tnear, -float_max);
    EXPECT_FALSE(restore_t(0.0f, {moved_tiny.shift, 0}, tiny).has_value());
}

TEST(RayConditioning, BatchesOfOrdinaryRaysAreNotCopied) {
    const std::vector<Ray> near = {{{0, 0, 5}, {0, 0, -1}, 0, kInfinity},
                                   {{2, 1, -3}, {0, 0, 1}, 0, kInfinity}};
    EXPECT_TRUE(condition_rays(near, kScene).rays.empty());
    std::vector<Ray> mixed = near;
    mixed.push_back({{1, 0, 1e20f}, {0, 0, -1e20f}, 0, kInfinity});
    mixed.push_back({{std::numeric_limits<float>::quiet_NaN(), 0, 1e20f}, {0, 0, -1}, 0, kInfinity});
    const ConditionedRays conditioned = condition_rays(mixed, kScene);
    ASSERT_EQ(conditioned.rays.size(), mixed.size());
    for (const std::size_t untouched : {0, 1, 3}) {
        EXPECT_EQ(conditioned.how[untouched].shift, 0.0) << untouched;
        EXPECT_EQ(conditioned.how[untouched].exponent, 0) << untouched;
    }
    // The direction 1e20 (2^66 < 1e20 < 2^67) is scaled by 2^-67, the interval by 2^67; the point nearest to
    // the centre (1, 0, 0.5) is at t' = 2^67 (1 - 2^-67), which rounds to the float shift 2^67: o + d,
    // exactly.
    EXPECT_EQ(conditioned.how[2].exponent, 67);
    EXPECT_EQ(conditioned.how[2].shift, 0x1p67);
    EXPECT_EQ(conditioned.rays[2].origin, Vec3f(1, 0, 0));
    EXPECT_EQ(conditioned.rays[2].direction, Vec3f(0, 0, -1e20f * 0x1p-67f));
    EXPECT_EQ(conditioned.rays[2].tnear, -0x1p67f);
    // The plane z = 0, which the conditioned ray meets at t' = 0, is at t = 1 of the caller's ray.
    std::vector<Hit> hits(mixed.size());
    hits[2] = {0.0f, 0, 0, 0};
    restore_hits(conditioned, mixed, hits);
    EXPECT_EQ(hits[2].t, 1.0f);
}

// Directions from denormal to 2^126: scaled by the power of two that brings the largest component into
// [1/2, 1), every component and the interval exactly, and t maps back exactly.
// The batch scan (vectorized with AVX2) answers as the per-ray predicate for every valid ray: ordinary rays,
// origins on and just past the far limit on each axis, direction components at and beside both thresholds,
// zero and denormal components, and the empty scene, which has nothing far.
TEST(RayConditioning, TheBatchScanAnswersAsThePerRayTest) {
    std::vector<float> coordinates = {0.0f, -0.0f, 1.0f, -3.5f, 1e-30f, 1e30f, -1e30f, 0x1p-140f};
    for (const float limit : {1.0f + 16.0f, -16.0f, 0.5f + 16.0f, 0.5f - 16.0f})
        coordinates.insert(coordinates.end(),
                           {limit, std::nextafter(limit, kInfinity), std::nextafter(limit, -kInfinity)});
    std::vector<float> components = {0.0f, -0.0f, 0.3f, -1.0f, 0x1p-149f, -0x1p-140f};
    for (const float threshold : {kDirectionLowest, kDirectionHighest}) {
        for (const float value :
             {threshold, std::nextafter(threshold, 0.0f), std::nextafter(threshold, kInfinity)})
            components.insert(components.end(), {value, -value});
    }
    std::mt19937 random(11);
    const auto pick = [&](const std::vector<float>& values) {
        return values[std::uniform_int_distribution<std::size_t>(0, values.size() - 1)(random)];
    };
    for (const Box3f& scene : {kScene, Box3f{}}) {
        const FarOriginFrame frame(scene);
        std::size_t flagged = 0, tested = 0;
        for (int i = 0; i < 200000; ++i) {
            const Ray ray{{pick(coordinates), pick(coordinates), pick(coordinates)},
                          {pick(components), pick(components), pick(components)},
                          0.0f,
                          kInfinity};
            if (!is_valid(ray)) continue;
            const bool expected = may_need_conditioning(ray, frame);
            ASSERT_EQ(any_may_need_conditioning(std::span(&ray, 1), frame), expected)
                << "o=(" << ray.origin.x << ", " << ray.origin.y << ", " << ray.origin.z << ") d=("
                << ray.direction.x << ", " << ray.direction.y << ", " << ray.direction.z << ")";
            flagged += expected ? 1 : 0;
            ++tested;
        }
        EXPECT_GT(flagged, tested / 10) << "both answers are exercised";
        EXPECT_LT(flagged, tested - tested / 10);
    }
    // A batch answers yes when any one ray does, wherever it stands.
    const FarOriginFrame frame(kScene);
    std::vector<Ray> batch(37, Ray{{1.0f, 0.0f, 0.5f}, {0.0f, 0.0f, -1.0f}, 0.0f, kInfinity});
    EXPECT_FALSE(any_may_need_conditioning(batch, frame));
    for (std::size_t far = 0; far < batch.size(); ++far) {
        std::vector<Ray> with_far = batch;
        with_far[far].origin.z = -1e30f;
        EXPECT_TRUE(any_may_need_conditioning(with_far, frame)) << far;
    }
}

TEST(RayConditioning, ExtremeDirectionsAreScaledExactly) {
    for (const float scale : {0x1p-149f, 0x1p-140f, 0x1p-127f, 0x1p-40f, 0x1p40f, 0x1p100f, 0x1p126f}) {
        const Ray ray{{0.25f, 0.5f, 0.75f}, Vec3f(-0.75f, 0.5f, 1.0f) * scale, 0.0f, 0x1p-30f / scale};
        const std::optional<std::pair<Ray, int>> scaled = scale_direction(ray);
        ASSERT_TRUE(scaled.has_value()) << scale;
        const auto& [conditioned, exponent] = *scaled;
        // At 2^-149 only the largest component survives the float (0.75 and 0.5 of it round away).
        if (scale >= 0x1p-127f) {
            EXPECT_EQ(conditioned.direction, Vec3f(-0.375f, 0.25f, 0.5f)) << scale;
        }
        EXPECT_EQ(max_component(abs(conditioned.direction)), 0.5f) << scale;
        EXPECT_EQ(conditioned.tfar, std::ldexp(ray.tfar, exponent)) << scale;
        const float t_hit = ray.tfar / 2.0f;
        EXPECT_EQ(restore_t(std::ldexp(t_hit, exponent), {0.0, exponent}, ray), t_hit) << scale;
    }
    EXPECT_FALSE(scale_direction({{0, 0, 0}, {0x1p-32f, 0, 0}, 0, kInfinity}).has_value());
    EXPECT_FALSE(scale_direction({{0, 0, 0}, {0, -0x1p32f, 1e-30f}, 0, kInfinity}).has_value());
}

// Beyond the float range: tnear is clamped to -FLT_MAX (no kernel returns less), tfar capped where the
// caller's t overflows, and a hit whose t would overflow is no hit.
TEST(RayConditioning, IntervalsBeyondTheFloatRangeStayValid) {
    const float float_max = std::numeric_limits<float>::max();
    const Ray huge{{0, 0, 0}, {0x1p100f, 0, 0}, -float_max, kInfinity};
    const Ray scaled_huge = scale_direction(huge)->first;
    EXPECT_EQ(scaled_huge.tnear, -float_max);
    EXPECT_EQ(scaled_huge.tfar, kInfinity);
    EXPECT_TRUE(is_valid(scaled_huge));
    const Ray tiny{{0, 0, 0}, {0x1p-140f, 0, 0}, 0, kInfinity};
    const auto [scaled_tiny, tiny_exponent] = *scale_direction(tiny);
    EXPECT_EQ(tiny_exponent, -139);
    EXPECT_EQ(scaled_tiny.tfar, std::ldexp(float_max, -139));
    EXPECT_FALSE(restore_t(1.0f, {0.0, tiny_exponent}, tiny).has_value()) << "t = 2^139 overflows";
}

// Scenes whose largest side lies in [2^-20, 2^20] are seen as they are; the others at the power of two that
// brings that side into [1/2, 1), a scene scaled up keeping its largest coordinate below 2^60
// (docs/numerical-contract.md, "Coordinate domain").
TEST(RayConditioning, SceneScaleBringsTheLargestSideIntoHalfToOne) {
    EXPECT_EQ(scene_scale_exponent(kScene), 0);
    EXPECT_EQ(scene_scale_exponent(Box3f{}), 0);
    EXPECT_EQ(scene_scale_exponent({Vec3f(5.0f), Vec3f(5.0f)}), 0);  // a point
    EXPECT_EQ(scene_scale_exponent({Vec3f(0.0f), {0x1p20f, 1, 1}}), 0);
    EXPECT_EQ(scene_scale_exponent({Vec3f(0.0f), {0x1.000002p20f, 1, 1}}), -21);
    EXPECT_EQ(scene_scale_exponent({Vec3f(-0x1p60f), Vec3f(0x1p60f)}), -62);
    EXPECT_EQ(scene_scale_exponent({Vec3f(0.0f), {0x1p-20f, 0, 0}}), 0);
    EXPECT_EQ(scene_scale_exponent({Vec3f(0.0f), {0x1.fffffep-21f, 0, 0}}), 20);
    EXPECT_EQ(scene_scale_exponent({Vec3f(0.0f), {0x1p-100f, 0, 0}}), 99);
    // At 2^40 from the origin, a side of 2^-30 is scaled up by 2^19 only: its coordinates reach 2^59.
    EXPECT_EQ(scene_scale_exponent({{0x1p40f, 0, 0}, {0x1p40f, 0x1p-30f, 0}}), 19);
    EXPECT_EQ(scene_scale_exponent({{0x1p30f, 0, 0}, {0x1p30f, 0x1p-40f, 0}}), 29);
}

// In a scene scaled by 2^s, every valid ray's origin and interval are scaled with it (after a far origin is
// moved and an extreme direction scaled), and t maps back exactly.
TEST(RayConditioning, RaysOfAScaledSceneAreScaledWithIt) {
    const Box3f scene{Vec3f(-0x1p50f), Vec3f(0x1p50f)};
    const int exponent = scene_scale_exponent(scene);
    ASSERT_EQ(exponent, -52);  // the side 2^51 scaled to 1/2
    const std::vector<Ray> rays = {{{0x1p49f, 3.0f, -5.0f}, {0, 0, 1}, -2.0f, 0x1p52f},
                                   {{0x1p49f, 3.0f, -5.0f}, {0, 0, 0x1p40f}, 0.0f, kInfinity},
                                   {{0x1p80f, 0, 0}, {-1, 0, 0}, 0.0f, kInfinity},
                                   {{0, 0, 0}, {0, 0, 0}, 0.0f, 1.0f}};  // invalid: left alone
    const ConditionedRays conditioned = condition_rays(rays, scene, exponent);
    ASSERT_EQ(conditioned.rays.size(), rays.size());
    const Ray& first = conditioned.rays[0];
    EXPECT_EQ(first.origin.x, 0x1p-3f);
    EXPECT_EQ(first.origin.y, 0x1.8p-51f);
    EXPECT_EQ(first.direction.z, 1.0f);
    EXPECT_EQ(first.tnear, -0x1p-51f);
    EXPECT_EQ(first.tfar, 1.0f);
    EXPECT_EQ(restore_t(0.5f, conditioned.how[0], rays[0]), 0x1p51f);
    // The direction scaled into [1/2, 1) as well: t' = t 2^41 2^-52.
    const Ray& second = conditioned.rays[1];
    EXPECT_EQ(second.direction.z, 0.5f);
    EXPECT_EQ(second.tfar, std::numeric_limits<float>::max() * 0x1p-11f);  // where the caller's t overflows
    EXPECT_EQ(restore_t(1.0f, conditioned.how[1], rays[1]), 0x1p11f);
    // The far origin moved near the scene first: the point of its line at t = 2^80, the centre, is t' = 0.
    const Ray& third = conditioned.rays[2];
    EXPECT_EQ(third.origin.x, 0.0f);
    EXPECT_EQ(restore_t(0.0f, conditioned.how[2], rays[2]), 0x1p80f);
    EXPECT_EQ(conditioned.how[3].exponent, 0);
    EXPECT_EQ(conditioned.how[3].shift, 0.0);
}

}  // namespace
}  // namespace lancer
