// The inverse of an instance's transform, in double: what moves a world ray into the object's frame
// (docs/numerical-contract.md, "Instances").
#pragma once

#include <cmath>
#include <limits>
#include <string>

#include "core/ray_conditioning.hpp"
#include "lancer/instances.hpp"
#include "lancer/ray.hpp"

namespace lancer {

// A world ray in an object's frame: t = t' + shift for a hit at t' on `ray`.
struct ObjectRay {
    Ray ray;
    double shift = 0.0;
};

// 96 bytes: p' = inverse (p - translation) for a point, inverse d for a direction.
struct InverseAffine {
    double inverse[3][3];
    double translation[3];
    // ||A||inf ||A^-1||inf, the max-norm condition number of the transform's linear part.
    double condition = 1.0;
    double norm = 1.0;  // ||A||inf

    // The world ray in the object's frame, and the shift of its parameter (t = t' + shift). An affine map
    // keeps a line's parameter when the direction is mapped with it, so the interval is the world's. Each
    // component is computed in double and rounded once to float. An origin farther than `far_limit` from
    // `object_centre` on some axis (ray conditioning's "far", against the object's box) is first moved along
    // the line, in double, to the point nearest the centre, as Accel::intersect would move it
    // (docs/numerical- contract.md, "Far origins"), and the interval with it, rounded outwards: done here, in
    // the double the map already works in, the object's own conditioning finds nothing to do.
    [[nodiscard]] ObjectRay to_object(const Ray& world, const Vec3f& object_centre, float far_limit) const {
        const double origin[3] = {double(world.origin.x) - translation[0],
                                  double(world.origin.y) - translation[1],
                                  double(world.origin.z) - translation[2]};
        const double direction[3] = {world.direction.x, world.direction.y, world.direction.z};
        double local_origin[3], local_direction[3];
        for (int r = 0; r < 3; ++r) {
            local_origin[r] =
                inverse[r][0] * origin[0] + inverse[r][1] * origin[1] + inverse[r][2] * origin[2];
            local_direction[r] =
                inverse[r][0] * direction[0] + inverse[r][1] * direction[1] + inverse[r][2] * direction[2];
        }
        ObjectRay local;
        local.ray.tnear = world.tnear;
        local.ray.tfar = world.tfar;
        double distance = 0.0;
        for (int r = 0; r < 3; ++r)
            distance = max_of_numbers(distance, std::fabs(local_origin[r] - double(object_centre[r])));
        if (distance > double(far_limit)) {
            double to_centre = 0.0, length_squared = 0.0;
            for (int r = 0; r < 3; ++r) {
                to_centre += (double(object_centre[r]) - local_origin[r]) * local_direction[r];
                length_squared += local_direction[r] * local_direction[r];
            }
            local.shift = to_centre / length_squared;
            for (int r = 0; r < 3; ++r)
                local_origin[r] += local.shift * local_direction[r];
            local.ray.tnear = max_of_numbers(round_down(double(world.tnear) - local.shift),
                                             -std::numeric_limits<float>::max());
            local.ray.tfar = round_up(double(world.tfar) - local.shift);
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
