// Rays and hits: the two records every query exchanges (and the `lancer rays` file formats, byte for byte).
#pragma once

#include <cstdint>
#include <limits>

#include "lancer/vec.hpp"

namespace lancer {

inline constexpr float kInfinity = std::numeric_limits<float>::infinity();

// 32 bytes, the layout of one record of a RAYS file: ox oy oz dx dy dz tnear tfar.
// The direction need not be unit length; t is measured in multiples of it.
struct Ray {
    Vec3f origin;     // 12 bytes
    Vec3f direction;  // 12 bytes
    float tnear = 0.0f;
    float tfar = kInfinity;
};
static_assert(sizeof(Ray) == 32);

// 16 bytes, the layout of one record of a HITS file.
// A triangle hit point is (1 - u - v) v0 + u v1 + v v2 with the vertices in file order.
struct Hit {
    float t = kInfinity;
    std::int32_t prim = -1;  // global primitive index, -1 on a miss
    float u = 0.0f;
    float v = 0.0f;

    [[nodiscard]] bool hit() const { return prim >= 0; }
};
static_assert(sizeof(Hit) == 16);

// The numerical contract (docs/numerical-contract.md): a ray with a NaN or infinite origin or direction
// component, a zero direction, a NaN or infinite tnear, a NaN tfar or tnear > tfar finds nothing.
// tfar may be +infinity. Every structure calls this once per ray, before any traversal, and so do the GPU
// kernels: it and closer are constexpr, which nvcc compiles for the device.
[[nodiscard]] constexpr bool is_valid(const Ray& ray) {
    return is_finite(ray.origin) && is_finite(ray.direction) &&
           (ray.direction.x != 0.0f || ray.direction.y != 0.0f || ray.direction.z != 0.0f) &&
           is_finite_number(ray.tnear) && ray.tfar == ray.tfar && ray.tnear <= ray.tfar;
}

// Closest-hit order shared by every structure so that all of them return the same answer on exact ties:
// the smaller t wins, and at equal t the smaller primitive index.
[[nodiscard]] constexpr bool closer(float t, std::int32_t prim, const Hit& best) {
    return t < best.t || (t == best.t && prim < best.prim);
}

}  // namespace lancer
