// The inverse of an instance's transform, in double: what moves a world ray into the object's frame
// (docs/numerical-contract.md, "Instances").
#pragma once

#include <string>

#include "lancer/instances.hpp"
#include "lancer/ray.hpp"

namespace lancer {

// 96 bytes: p' = inverse (p - translation) for a point, inverse d for a direction.
struct InverseAffine {
    double inverse[3][3];
    double translation[3];
    // ||A||inf ||A^-1||inf, the max-norm condition number of the transform's linear part.
    double condition = 1.0;
    double norm = 1.0;  // ||A||inf

    // The world ray in the object's frame, its interval unchanged: an affine map keeps a line's parameter
    // when the direction is mapped with it. Each component computed in double and rounded once to float.
    [[nodiscard]] Ray to_object(const Ray& world) const {
        const double origin[3] = {double(world.origin.x) - translation[0],
                                  double(world.origin.y) - translation[1],
                                  double(world.origin.z) - translation[2]};
        const double direction[3] = {world.direction.x, world.direction.y, world.direction.z};
        Ray local;
        for (int r = 0; r < 3; ++r) {
            local.origin[r] = static_cast<float>(inverse[r][0] * origin[0] + inverse[r][1] * origin[1] +
                                                 inverse[r][2] * origin[2]);
            local.direction[r] = static_cast<float>(
                inverse[r][0] * direction[0] + inverse[r][1] * direction[1] + inverse[r][2] * direction[2]);
        }
        local.tnear = world.tnear;
        local.tfar = world.tfar;
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
