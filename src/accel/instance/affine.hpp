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
