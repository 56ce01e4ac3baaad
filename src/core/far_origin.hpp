// Rays from far away, moved near the scene before any structure sees them (docs/numerical-contract.md, "Far
// origins"; fuzz finding 11 of docs/robustness.md).
//
// Every kernel works in the ray's frame: the watertight test translates the vertices by the origin, the slab
// test subtracts it from the planes. A float origin at distance D from the scene rounds those differences to
// ulp(D), so a ray from 4.5e11 away sees a 5-unit scene through a 2^15-unit grid and brute force reports a
// "hit" on a triangle that the exact line misses by more than a unit. The line itself is exact, though: it is
// the rounding of o + t d, not the ray, that is lost. So a far ray is re-parametrised exactly from the point
// of its line nearest to the scene's centre, computed in double (a float product is exact in double, and
// the sum rounds at 2^-53 of D, far below the scene's own ulp), then rounded to float once: the new origin
// lies near the scene and every kernel sees the line to a few ulps of the scene's coordinates.
#pragma once

#include <cmath>
#include <limits>
#include <optional>

#include "lancer/box.hpp"
#include "lancer/ray.hpp"

namespace lancer {

// A ray is far when its origin lies more than this many half-extents of the scene's box from the box's
// centre (per axis). Rays from closer keep their origin, and their bits: a kernel's error then stays within
// 2^-24 * 2^9 = 2^-15 of the scene's size. Cameras of the benchmark views stand 1 to 3 extents away.
inline constexpr float kFarOriginHalfExtents = 256.0f;

// What the re-parametrisation needs of the scene: its box's centre and the distance beyond which an origin
// is far. An empty scene has no centre: nothing is far (there is nothing to hit).
class FarOriginFrame {
  public:
    explicit FarOriginFrame(const Box3f& bounds)
        : active_(!bounds.empty()),
          centre_(bounds.center()),
          far_distance_(kFarOriginHalfExtents * 0.5f * max_component(bounds.extent())) {}

    // Valid rays only (is_valid): an infinite origin is not far, it is invalid.
    [[nodiscard]] bool is_far(const Ray& ray) const {
        return active_ && max_component(abs(ray.origin - centre_)) > far_distance_;
    }

    // The same line from its point nearest to the centre: origin o + s d and interval [tnear - s, tfar - s],
    // with the shift s returned beside it (t = t' + s, see restore_t). None when s is beyond the float range:
    // t cannot reach the scene then, and the ray keeps its origin.
    struct Moved {
        Ray ray;
        double shift;
    };
    [[nodiscard]] std::optional<Moved> move_near(const Ray& ray) const {
        const double dx = ray.direction.x, dy = ray.direction.y, dz = ray.direction.z;
        const double to_centre = (double(centre_.x) - ray.origin.x) * dx +
                                 (double(centre_.y) - ray.origin.y) * dy +
                                 (double(centre_.z) - ray.origin.z) * dz;
        // A float shift keeps o + s d exact in double: s d is a product of two 24-bit significands.
        const float shift = static_cast<float>(to_centre / (dx * dx + dy * dy + dz * dz));
        if (!std::isfinite(shift)) return std::nullopt;
        const double s = shift;
        Ray moved = ray;
        moved.origin =
            Vec3f(static_cast<float>(ray.origin.x + s * dx), static_cast<float>(ray.origin.y + s * dy),
                  static_cast<float>(ray.origin.z + s * dz));
        // The interval rounded outwards, so that no hit inside [tnear, tfar] is lost; restore_t clamps. A
        // tnear that overflows would make the ray invalid: the ray then keeps its origin.
        moved.tnear = round_down(double(ray.tnear) - s);
        moved.tfar = std::isinf(ray.tfar) ? ray.tfar : round_up(double(ray.tfar) - s);
        if (!std::isfinite(moved.tnear)) return std::nullopt;
        return Moved{moved, s};
    }

    // A moved ray's t back in the caller's parametrisation, within the caller's [tnear, tfar].
    [[nodiscard]] static float restore_t(float moved_t, double shift, const Ray& original) {
        const float t = static_cast<float>(double(moved_t) + shift);
        return std::fmin(std::fmax(t, original.tnear), original.tfar);
    }

  private:
    static float round_down(double value) {
        const float rounded = static_cast<float>(value);
        return double(rounded) > value ? std::nextafter(rounded, -kInfinity) : rounded;
    }
    static float round_up(double value) {
        const float rounded = static_cast<float>(value);
        return double(rounded) < value ? std::nextafter(rounded, kInfinity) : rounded;
    }

    bool active_;
    Vec3f centre_;
    float far_distance_;
};

}  // namespace lancer
