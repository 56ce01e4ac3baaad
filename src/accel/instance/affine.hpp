// The inverse of an instance's transform, in double: what moves a world ray into the object's frame
// (docs/numerical-contract.md, "Instances").
#pragma once

#include <cmath>
#include <limits>
#include <string>
#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include "core/ray_conditioning.hpp"
#include "lancer/instances.hpp"
#include "lancer/ray.hpp"

namespace lancer {

// A world ray in an object's frame: t = t' + shift for a hit at t' on `ray`.
struct ObjectRay {
    Ray ray;
    double shift = 0.0;
};

#if defined(__AVX2__)
// Four doubles, one ray's coordinate each, with double's + - * / lane by lane: InverseAffine's steps below
// run for four rays at once, each lane by the one-ray steps' operations (the build does not contract them
// into FMAs).
struct DoubleLanes {
    __m256d lanes;

    explicit DoubleLanes(double x) : lanes(_mm256_set1_pd(x)) {}
    explicit DoubleLanes(__m256d x) : lanes(x) {}
    friend DoubleLanes operator+(DoubleLanes a, DoubleLanes b) {
        return DoubleLanes(_mm256_add_pd(a.lanes, b.lanes));
    }
    friend DoubleLanes operator-(DoubleLanes a, DoubleLanes b) {
        return DoubleLanes(_mm256_sub_pd(a.lanes, b.lanes));
    }
    friend DoubleLanes operator*(DoubleLanes a, DoubleLanes b) {
        return DoubleLanes(_mm256_mul_pd(a.lanes, b.lanes));
    }
    friend DoubleLanes operator/(DoubleLanes a, DoubleLanes b) {
        return DoubleLanes(_mm256_div_pd(a.lanes, b.lanes));
    }
};
#endif

#if defined(__AVX2__)
// next_float_up (core/ray_conditioning.hpp) on four floats: the next float up, +inf kept, the least denormal
// after a zero of either sign.
[[nodiscard]] inline __m128 next_float_up_lanes(__m128 value) {
    const __m128i bits = _mm_castps_si128(value);
    const __m128 stepped = _mm_blendv_ps(_mm_castsi128_ps(_mm_sub_epi32(bits, _mm_set1_epi32(1))),
                                         _mm_castsi128_ps(_mm_add_epi32(bits, _mm_set1_epi32(1))),
                                         _mm_cmpgt_ps(value, _mm_setzero_ps()));
    const __m128 off_zero = _mm_blendv_ps(stepped, _mm_set1_ps(std::numeric_limits<float>::denorm_min()),
                                          _mm_cmpeq_ps(value, _mm_setzero_ps()));
    return _mm_blendv_ps(off_zero, value, _mm_cmpeq_ps(value, _mm_set1_ps(kInfinity)));
}

// A mask of four doubles' lanes as a mask of four floats' lanes.
[[nodiscard]] inline __m128 narrow_mask(__m256d mask) {
    return _mm256_castps256_ps128(
        _mm256_permutevar8x32_ps(_mm256_castpd_ps(mask), _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7)));
}

// round_down and round_up on four doubles, each lane by their rule, with masks where they branch: a walk that
// moves the intervals of many rays rounds about half of them each way, so branches would be mispredicted
// half the time (docs/accel/instances.md, "Kept: the far lanes' intervals without branches").
[[nodiscard]] inline __m128 round_down_lanes(__m256d value) {
    const __m128 rounded = _mm256_cvtpd_ps(value);
    const __m128 above = narrow_mask(_mm256_cmp_pd(_mm256_cvtps_pd(rounded), value, _CMP_GT_OQ));
    const __m128 sign = _mm_set1_ps(-0.0f);  // next_float_down(x) = -next_float_up(-x)
    return _mm_blendv_ps(rounded, _mm_xor_ps(next_float_up_lanes(_mm_xor_ps(rounded, sign)), sign), above);
}
[[nodiscard]] inline __m128 round_up_lanes(__m256d value) {
    const __m128 rounded = _mm256_cvtpd_ps(value);
    const __m128 below = narrow_mask(_mm256_cmp_pd(_mm256_cvtps_pd(rounded), value, _CMP_LT_OQ));
    return _mm_blendv_ps(rounded, next_float_up_lanes(rounded), below);
}
#endif

// 96 bytes: p' = inverse (p - translation) for a point, inverse d for a direction.
struct InverseAffine {
    double inverse[3][3];
    double translation[3];
    // ||A||inf ||A^-1||inf, the max-norm condition number of the transform's linear part.
    double condition = 1.0;
    double norm = 1.0;  // ||A||inf

    // p' and d' of a world origin and direction, each row's three products summed left to right. Real is
    // double for one ray, or DoubleLanes for four: one source, so that every lane holds the one-ray map's
    // bits. So do the far-origin move's steps below.
    template <class Real>
    void map(const Real (&origin)[3], const Real (&direction)[3], Real (&local_origin)[3],
             Real (&local_direction)[3]) const {
        const Real moved[3] = {origin[0] - Real(translation[0]), origin[1] - Real(translation[1]),
                               origin[2] - Real(translation[2])};
        for (int r = 0; r < 3; ++r) {
            const Real row[3] = {Real(inverse[r][0]), Real(inverse[r][1]), Real(inverse[r][2])};
            local_origin[r] = row[0] * moved[0] + row[1] * moved[1] + row[2] * moved[2];
            local_direction[r] = row[0] * direction[0] + row[1] * direction[1] + row[2] * direction[2];
        }
    }

    // A far origin moved along its line to the point nearest `centre`: the shift s returned, the origin
    // moved by s d.
    template <class Real>
    static Real move_towards(const Real (&centre)[3], Real (&local_origin)[3],
                             const Real (&local_direction)[3]) {
        Real to_centre(0.0), length_squared(0.0);
        for (int r = 0; r < 3; ++r) {
            to_centre = to_centre + (centre[r] - local_origin[r]) * local_direction[r];
            length_squared = length_squared + local_direction[r] * local_direction[r];
        }
        const Real shift = to_centre / length_squared;
        for (int r = 0; r < 3; ++r)
            local_origin[r] = local_origin[r] + shift * local_direction[r];
        return shift;
    }

    // The world interval [world_tnear, world_tfar] moved with the origin (t' = t - shift), rounded outwards.
    static void move_interval(float world_tnear, float world_tfar, double shift, float& tnear, float& tfar) {
        tnear = max_of_numbers(round_down(double(world_tnear) - shift), -std::numeric_limits<float>::max());
        tfar = round_up(double(world_tfar) - shift);
    }
#if defined(__AVX2__)
    // The same for four rays, lane by lane. MAXPS is max_of_numbers (the second operand unless the first is
    // greater), and the roundings are round_down's and round_up's (round_down_lanes).
    static void move_interval(__m128 world_tnear, __m128 world_tfar, DoubleLanes shift, __m128& tnear,
                              __m128& tfar) {
        tnear = _mm_max_ps(round_down_lanes(_mm256_sub_pd(_mm256_cvtps_pd(world_tnear), shift.lanes)),
                           _mm_set1_ps(-std::numeric_limits<float>::max()));
        tfar = round_up_lanes(_mm256_sub_pd(_mm256_cvtps_pd(world_tfar), shift.lanes));
    }
#endif

    // The world ray in the object's frame, and the shift of its parameter (t = t' + shift). An affine map
    // keeps a line's parameter when the direction is mapped with it, so the interval is the world's. Each
    // component is computed in double and rounded once to float. An origin farther than `far_limit` from
    // `object_centre` on some axis (ray conditioning's "far", against the object's box) is first moved along
    // the line, in double, to the point nearest the centre, as Accel::intersect would move it
    // (docs/numerical- contract.md, "Far origins"), and the interval with it, rounded outwards: done here, in
    // the double the map already works in, the object's own conditioning finds nothing to do.
    [[nodiscard]] ObjectRay to_object(const Ray& world, const Vec3f& object_centre, float far_limit) const {
        const double origin[3] = {world.origin.x, world.origin.y, world.origin.z};
        const double direction[3] = {world.direction.x, world.direction.y, world.direction.z};
        double local_origin[3], local_direction[3];
        map(origin, direction, local_origin, local_direction);
        ObjectRay local;
        local.ray.tnear = world.tnear;
        local.ray.tfar = world.tfar;
        double distance = 0.0;
        for (int r = 0; r < 3; ++r)
            distance = max_of_numbers(distance, std::fabs(local_origin[r] - double(object_centre[r])));
        if (distance > double(far_limit)) {
            const double centre[3] = {object_centre.x, object_centre.y, object_centre.z};
            local.shift = move_towards(centre, local_origin, local_direction);
            move_interval(world.tnear, world.tfar, local.shift, local.ray.tnear, local.ray.tfar);
        }
        for (int r = 0; r < 3; ++r) {
            local.ray.origin[r] = static_cast<float>(local_origin[r]);
            local.ray.direction[r] = static_cast<float>(local_direction[r]);
        }
        return local;
    }
};

// Transforms whose condition number passes this are refused: the inverse computed in double then errs by up
// to condition x 2^-53 relative, beyond half of float's 2^-24 rounding of the object ray.
inline constexpr double kMaxCondition = 0x1p29;

// The inverse of `transform`. `problem` is set to what makes the transform unusable (a NaN or infinite entry,
// a singular or too ill-conditioned linear part), and left empty when it is usable.
[[nodiscard]] InverseAffine invert(const Transform& transform, std::string& problem);

}  // namespace lancer
