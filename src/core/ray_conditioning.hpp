// Rays conditioned once per batch, before any structure sees them, the same way for every structure (and the
// CUDA tracer): a direction near the ends of the float range is scaled by a power of two, a ray from far
// away is moved near the scene along its line, and in a scene whose size lies outside the ordinary range,
// which the structures see scaled by a power of two, the origin and interval are scaled with it; t is mapped
// back after the trace. So every kernel works on products that neither overflow nor underflow, rounded at
// the scene's scale, not at the origin's distance: docs/numerical-contract.md, "Ray conditioning", "Far
// origins" and "Coordinate domain".
#pragma once

#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "lancer/box.hpp"
#include "lancer/packet.hpp"
#include "lancer/ray.hpp"

namespace lancer {

// A ray is far when its origin lies more than kFarOriginSides times the largest side of the scene's box from
// the box's centre on some axis. Rays from closer keep their origin, and their bits: every vertex lies within
// |T| <= (kFarOriginSides + 1/2) sides of the origin (max norm). The benchmark cameras stand within 2.4
// sides of the centre (2.74 half-diagonals of the box).
inline constexpr float kFarOriginSides = 4.0f;

// The structures treat their boxes and cells as grown by the geometric tolerance (accel/build_util.hpp):
// 2^-20 of the scene's largest coordinate, for the rounding of coordinates, plus kKernelTolerance times its
// largest side, which covers the distance from the exact line at which a triangle test may report a hit.
// The watertight test translates and shears the vertices, rounding each by a few 2^-24 |T| before its edge
// functions (up to 1.9 2^-24 |T| measured in 113-bit arithmetic on rays aimed just outside vertices;
// tests/accel/build_util_test.cpp asserts the consequence); Moller-Trumbore decides in double within its
// error bound of an edge (core/intersect.hpp). A budget of 6 2^-24 |T| at the threshold:
inline constexpr float kKernelTolerance = 0x1p-19f;
static_assert(kKernelTolerance >= 6.0f * (kFarOriginSides + 0.5f) * 0x1p-24f);

// The float after `value` towards +inf, and the one before it towards -inf: std::nextafter(value, +-inf) for
// a value that is not NaN, without the library call (whose call clobbers every vector register: the instance
// walk's double map spilled its state around three of them, docs/accel/instances.md). An infinity towards
// itself stays; either zero steps to the smallest subnormal of the direction's sign.
[[nodiscard]] inline float next_float_up(float value) {
    if (value == kInfinity) return value;
    if (value == 0.0f) return std::numeric_limits<float>::denorm_min();
    const auto bits = std::bit_cast<std::uint32_t>(value);
    return std::bit_cast<float>(value > 0.0f ? bits + 1 : bits - 1);
}
[[nodiscard]] inline float next_float_down(float value) {
    return -next_float_up(-value);
}

// The larger and the smaller of two numbers neither of which is NaN, as std::fmax and std::fmin (glibc's
// maxsd/minsd, which return the second operand on equal ones, -0 and +0 among them) without the call.
template <class T>
[[nodiscard]] inline T max_of_numbers(T a, T b) {
    return a > b ? a : b;
}
template <class T>
[[nodiscard]] inline T min_of_numbers(T a, T b) {
    return a < b ? a : b;
}

// A double rounded to the float at or below it, and at or above it (beyond FLT_MAX: +inf).
[[nodiscard]] inline float round_down(double value) {
    const float rounded = static_cast<float>(value);
    return double(rounded) > value ? next_float_down(rounded) : rounded;
}
[[nodiscard]] inline float round_up(double value) {
    const float rounded = static_cast<float>(value);
    return double(rounded) < value ? next_float_up(rounded) : rounded;
}

// What the re-parametrisation needs of the scene: its box's centre and the distance beyond which an origin
// is far. An empty scene has no centre: nothing is far (there is nothing to hit).
class FarOriginFrame {
  public:
    explicit FarOriginFrame(const Box3f& bounds)
        : active_(!bounds.empty()),
          centre_(bounds.center()),
          far_distance_(kFarOriginSides * max_component(bounds.extent())) {}

    // The origin of a valid ray (is_valid): an infinite origin is not far, it is invalid.
    [[nodiscard]] bool is_far(Vec3f origin) const {
        return active_ && max_component(abs(origin - centre_)) > far_distance_;
    }
    [[nodiscard]] Vec3f centre() const { return centre_; }
    // The distance from the centre on some axis beyond which an origin is far: +inf for an empty scene.
    [[nodiscard]] float far_limit() const { return active_ ? far_distance_ : kInfinity; }

    // The same line from a point near the one nearest to the centre: origin o + s d and interval
    // [tnear - s, tfar - s], with the shift s returned beside it (t = t' + s). The interval is the caller's
    // in double, so that one beyond the float range (a direction scaled by scale_direction) is moved
    // exactly. The shift itself may pass the float range: from an origin near FLT_MAX along a direction
    // shorter than 1 the scene lies beyond t = -FLT_MAX, and such a ray left at its far origin would be
    // answered by rounding noise (docs/numerical-contract.md, "Far origins"). The ray must be valid
    // (is_valid): a finite origin and a non-zero finite direction keep every shift a finite double.
    struct Moved {
        Ray ray;
        double shift;
    };
    [[nodiscard]] Moved move_near(const Ray& ray, double tnear, double tfar) const {
        // The point is kept as an unevaluated sum point + error per axis and moved by shifts of float
        // precision (24 bits, of any double exponent): such a shift times a float component is exact in
        // double, and two_sum adds it without error, so the point stays on the caller's line; each round
        // brings it 2^24 times closer to the centre (the shift's own rounding), until it is no longer far.
        // What is left is the rounding of the small error terms, about 2^-130 of the first distance, and the
        // one rounding of the result to float near the scene.
        const double direction[3] = {ray.direction.x, ray.direction.y, ray.direction.z};
        const double length_squared =
            direction[0] * direction[0] + direction[1] * direction[1] + direction[2] * direction[2];
        double point[3] = {ray.origin.x, ray.origin.y, ray.origin.z}, error[3] = {0.0, 0.0, 0.0};
        double shift = 0.0;
        for (int round = 0; round < kMaxRounds; ++round) {
            double to_centre = 0.0;
            for (int axis = 0; axis < 3; ++axis)
                to_centre += ((double(centre_[axis]) - point[axis]) - error[axis]) * direction[axis];
            const double step = to_float_precision(to_centre / length_squared);
            if (step == 0.0) break;
            for (int axis = 0; axis < 3; ++axis) {
                const auto [sum, rounding] = two_sum(point[axis], step * direction[axis]);
                point[axis] = sum;
                error[axis] += rounding;
            }
            shift += step;
            if (!is_far(rounded(point, error))) break;
        }
        Ray moved = ray;
        moved.origin = rounded(point, error);
        // The interval rounded outwards, so that no hit inside [tnear, tfar] is lost; restore_t clamps. A
        // tnear below -FLT_MAX admits every t a kernel can return (as in scale_direction).
        moved.tnear = std::fmax(round_down(tnear - shift), -std::numeric_limits<float>::max());
        moved.tfar = round_up(tfar - shift);  // an infinite tfar stays infinite
        return Moved{moved, shift};
    }

  private:
    // Enough rounds to come from FLT_MAX to an ulp of the smallest normal float, 24 bits a round.
    static constexpr int kMaxRounds = 12;

    // value rounded to float's 24 significant bits, its exponent kept (frexp's mantissa lies in [1/2, 1)).
    static double to_float_precision(double value) {
        int exponent = 0;
        const double mantissa = std::frexp(value, &exponent);
        return std::ldexp(double(static_cast<float>(mantissa)), exponent);
    }
    // Knuth's TwoSum: a + b = sum + rounding exactly (round-to-nearest, no contraction: -ffp-contract=off).
    static std::pair<double, double> two_sum(double a, double b) {
        const double sum = a + b;
        const double b_part = sum - a;
        return {sum, (a - (sum - b_part)) + (b - b_part)};
    }
    static Vec3f rounded(const double (&point)[3], const double (&error)[3]) {
        return {static_cast<float>(point[0] + error[0]), static_cast<float>(point[1] + error[1]),
                static_cast<float>(point[2] + error[2])};
    }

    bool active_;
    Vec3f centre_;
    float far_distance_;
};

// Directions whose largest component lies in [2^-32, 2^32] are used as given (every ordinary ray); the
// others are scaled by a power of two into [1/2, 1).
inline constexpr float kDirectionLowest = 0x1p-32f, kDirectionHighest = 0x1p32f;

// Scenes whose largest side lies in [2^-20, 2^20] are traced as they are, bit for bit. The others are given
// to the structures scaled by a power of two that brings their largest side into [1/2, 1): the kernels form
// products of up to three lengths and a direction (the watertight test's numerator reaches 2^43.1 X^3 for a
// scene of largest side X and a direction of 2^-32), which stay within float's normal range for X in
// [2^-37, 2^28] (docs/numerical-contract.md, "Coordinate domain", has the derivation).
inline constexpr float kOrdinarySideLowest = 0x1p-20f, kOrdinarySideHighest = 0x1p20f;

// The exponent s of the scale 2^s at which the structures see a scene of box `bounds`: 0 for an ordinary
// scene, an empty one or a point. A scene scaled up keeps its largest coordinate below 2^60, inside the
// domain: one whose side is below about 2^-97 of its largest coordinate is scaled up only that far.
[[nodiscard]] inline int scene_scale_exponent(const Box3f& bounds) {
    if (bounds.empty()) return 0;
    const float side = max_component(bounds.extent());
    if (!(side > 0.0f) || (side >= kOrdinarySideLowest && side <= kOrdinarySideHighest)) return 0;
    int side_exponent = 0;  // side in [2^(side_exponent - 1), 2^side_exponent)
    static_cast<void>(std::frexp(side, &side_exponent));
    if (side_exponent > 0) return -side_exponent;
    int coordinate_exponent = 0;
    static_cast<void>(std::frexp(std::fmax(max_component(abs(bounds.lo)), max_component(abs(bounds.hi))),
                                 &coordinate_exponent));
    return std::max(0, std::min(-side_exponent, 60 - coordinate_exponent));
}

// How a conditioned ray maps back: the caller's t = (t' + shift) * 2^-exponent.
struct RayConditioning {
    double shift = 0.0;
    int exponent = 0;
};

// The caller's t of a conditioned ray's hit; none when it overflows (a hit is at a finite distance).
[[nodiscard]] inline std::optional<float> restore_t(float conditioned_t, const RayConditioning& how,
                                                    const Ray& original) {
    const float t = static_cast<float>(std::ldexp(double(conditioned_t) + how.shift, -how.exponent));
    if (!std::isfinite(t)) return std::nullopt;
    return std::fmin(std::fmax(t, original.tnear), original.tfar);
}

// The batch as the structures see it, and how each ray maps back; empty when no ray needs conditioning (the
// common case, which then costs one pass over the rays).
struct ConditionedRays {
    std::vector<Ray> rays;
    std::vector<RayConditioning> how;  // per ray; {0, 0} for the rays left as they were
};

// The caller's interval in the units of a direction scaled by 2^-exponent, in double: tnear exactly, tfar
// capped where the caller's t would overflow, so that no hit maps back to infinity and occluded, which maps
// nothing back, answers as closest hit does (docs/numerical-contract.md, "Far origins").
[[nodiscard]] inline std::pair<double, double> scaled_interval(const Ray& ray, int exponent) {
    return {std::ldexp(double(ray.tnear), exponent),
            std::ldexp(std::fmin(double(ray.tfar), double(std::numeric_limits<float>::max())), exponent)};
}

// A valid ray with its direction scaled into [1/2, 1) and its interval scaled back, or none when its
// direction is ordinary. Exact, except for a component below 2^-126 of the largest, which underflows (the
// line turns by less than 2^-126 rad).
[[nodiscard]] inline std::optional<std::pair<Ray, int>> scale_direction(const Ray& ray) {
    const float largest = max_component(abs(ray.direction));
    if (largest >= kDirectionLowest && largest <= kDirectionHighest) return std::nullopt;
    int exponent = 0;
    static_cast<void>(std::frexp(largest, &exponent));
    Ray scaled = ray;
    scaled.direction = {std::ldexp(ray.direction.x, -exponent), std::ldexp(ray.direction.y, -exponent),
                        std::ldexp(ray.direction.z, -exponent)};
    // The interval in the new units, in float: a tnear below -FLT_MAX admits every t a kernel can return,
    // and a capped tfar beyond FLT_MAX every t too.
    constexpr double kFloatMax = std::numeric_limits<float>::max();
    const auto [tnear, tfar] = scaled_interval(ray, exponent);
    scaled.tnear = static_cast<float>(std::fmax(tnear, -kFloatMax));
    scaled.tfar = tfar > kFloatMax ? kInfinity : static_cast<float>(tfar);
    return std::pair{scaled, exponent};
}

// Whether a ray may need conditioning: a direction outside the ordinary range or a far origin. Invalid rays
// may answer yes (their NaN comparisons fail); condition_rays then leaves them to miss. Written without
// branches, so that the scan of a batch of ordinary rays stays a few compares per ray.
[[nodiscard]] inline bool may_need_conditioning(const Ray& ray, const FarOriginFrame& frame) {
    const float largest = max_component(abs(ray.direction));
    return !(largest >= kDirectionLowest) | !(largest <= kDirectionHighest) | frame.is_far(ray.origin);
}

// Whether some ray of the batch may need conditioning: the same answer as may_need_conditioning's for every
// valid ray (an invalid one, which condition_rays leaves alone, may answer either way). With AVX2 a ray is
// one vector of its 8 floats (origin, direction, tnear, tfar), and two compares decide it: an origin
// coordinate beyond the far limit or a direction component above kDirectionHighest, or no direction component
// at or above kDirectionLowest. The scan runs on every batch of every structure, and GCC does not vectorize
// the scalar loop (docs/numerical-contract.md, "Ray conditioning").
[[nodiscard]] inline bool any_may_need_conditioning(std::span<const Ray> rays, const FarOriginFrame& frame) {
#if defined(__AVX2__)
    static_assert(sizeof(Ray) == 8 * sizeof(float) && offsetof(Ray, direction) == 3 * sizeof(float) &&
                  offsetof(Ray, tnear) == 6 * sizeof(float) && offsetof(Ray, tfar) == 7 * sizeof(float));
    const Vec3f c = frame.centre();
    const float far = frame.far_limit();
    const __m256 centre = _mm256_setr_ps(c.x, c.y, c.z, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f);
    const __m256 upper = _mm256_setr_ps(far, far, far, kDirectionHighest, kDirectionHighest,
                                        kDirectionHighest, kInfinity, kInfinity);
    const __m256 lower = _mm256_setr_ps(kInfinity, kInfinity, kInfinity, kDirectionLowest, kDirectionLowest,
                                        kDirectionLowest, kInfinity, kInfinity);
    const __m256 sign = _mm256_set1_ps(-0.0f);
    constexpr int kPosition = 0x3f, kDirection = 0x38;  // lanes 0-5, lanes 3-5
    bool any = false;
    for (const Ray& ray : rays) {
        const __m256 distance = _mm256_andnot_ps(sign, _mm256_sub_ps(_mm256_loadu_ps(&ray.origin.x), centre));
        const int beyond = _mm256_movemask_ps(_mm256_cmp_ps(distance, upper, _CMP_GT_OQ));
        const int ordinary = _mm256_movemask_ps(_mm256_cmp_ps(distance, lower, _CMP_GE_OQ));
        any |= ((beyond & kPosition) != 0) | ((ordinary & kDirection) == 0);
    }
    return any;
#else
    bool any = false;
    for (const Ray& ray : rays)
        any |= may_need_conditioning(ray, frame);
    return any;
#endif
}

// The same question for lanes [0, size) of a packet: may_need_conditioning lane by lane, which GCC vectorizes
// over the packet's contiguous arrays once the answer is accumulated as an int (with a bool accumulator GCC
// 12 keeps the loop scalar).
[[nodiscard]] inline bool any_may_need_conditioning(const RayPacket& rays, const FarOriginFrame& frame) {
    int any = 0;
    for (int lane = 0; lane < rays.size; ++lane)
        any |= may_need_conditioning(rays.ray(lane), frame);
    return any != 0;
}

// The batch as the structures of a scene of box `scene_bounds` (the caller's units) see it, the scene scaled
// by 2^scene_exponent (scene_scale_exponent). Every valid ray of a scaled scene is conditioned; in an
// ordinary one only the rays that may need it, after one scan of the batch.
[[nodiscard]] inline ConditionedRays condition_rays(std::span<const Ray> rays, const Box3f& scene_bounds,
                                                    int scene_exponent = 0) {
    const FarOriginFrame frame(scene_bounds);
    ConditionedRays conditioned;
    if (scene_exponent == 0 && !any_may_need_conditioning(rays, frame)) return conditioned;
    // A float times it is exact in double, its one rounding to float ldexp's (and cheaper than ldexp).
    const double scene_scale = std::ldexp(1.0, scene_exponent);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (scene_exponent == 0 && !may_need_conditioning(rays[i], frame)) continue;
        if (!is_valid(rays[i])) continue;
        Ray ray = rays[i];
        RayConditioning how;
        if (const auto scaled = scale_direction(ray)) std::tie(ray, how.exponent) = *scaled;
        if (frame.is_far(ray.origin)) {
            // Moved from the caller's interval in double, not from scale_direction's float one.
            const auto [tnear, tfar] = scaled_interval(rays[i], how.exponent);
            const FarOriginFrame::Moved near = frame.move_near(ray, tnear, tfar);
            ray = near.ray, how.shift = near.shift;
        }
        if (scene_exponent != 0) {
            // The origin, now within kFarOriginSides sides of the scene, scaled with it (exactly, but for an
            // underflow far below the scene's rounding), and the interval from the caller's in double,
            // rounded outwards once: t' = (t - shift) * 2^scene_exponent in the scaled direction's units.
            ray.origin = {static_cast<float>(ray.origin.x * scene_scale),
                          static_cast<float>(ray.origin.y * scene_scale),
                          static_cast<float>(ray.origin.z * scene_scale)};
            const auto [tnear, tfar] = scaled_interval(rays[i], how.exponent);
            ray.tnear =
                std::fmax(round_down((tnear - how.shift) * scene_scale), -std::numeric_limits<float>::max());
            ray.tfar = round_up((tfar - how.shift) * scene_scale);  // past FLT_MAX: +inf
            how.shift *= scene_scale;
            how.exponent += scene_exponent;
        } else if (how.shift == 0.0 && how.exponent == 0) {
            continue;
        }
        if (conditioned.rays.empty())
            conditioned.rays.assign(rays.begin(), rays.end()), conditioned.how.assign(rays.size(), {});
        conditioned.rays[i] = ray;
        conditioned.how[i] = how;
    }
    return conditioned;
}

// The hits of the conditioned rays back in the callers' parametrisation: `hits` indexes Hit records, or any
// with t and hit() whose default is a miss (the two-level scenes' InstanceHit).
template <class Hits>
inline void restore_hits(const ConditionedRays& conditioned, std::span<const Ray> rays, Hits&& hits) {
    for (std::size_t i = 0; i < conditioned.how.size(); ++i) {
        const RayConditioning& how = conditioned.how[i];
        if ((how.shift == 0.0 && how.exponent == 0) || !hits[i].hit()) continue;
        const std::optional<float> t = restore_t(hits[i].t, how, rays[i]);
        if (t) {
            hits[i].t = *t;
        } else {
            hits[i] = std::remove_cvref_t<decltype(hits[i])>{};
        }
    }
}

}  // namespace lancer
