// Small fixed-size vector used everywhere in lancer: fp32 throughout (the paper's and Embree's precision).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace lancer {

struct Vec3f {
    float x = 0.0f, y = 0.0f, z = 0.0f;

    constexpr Vec3f() = default;
    constexpr Vec3f(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    constexpr explicit Vec3f(float s) : x(s), y(s), z(s) {}

    // A ternary chain rather than (&x)[i]: well defined, and compilers turn it into a select.
    [[nodiscard]] constexpr float operator[](int axis) const { return axis == 0 ? x : (axis == 1 ? y : z); }
    constexpr float& operator[](int axis) { return axis == 0 ? x : (axis == 1 ? y : z); }

    constexpr Vec3f& operator+=(const Vec3f& o) {
        x += o.x, y += o.y, z += o.z;
        return *this;
    }
    constexpr Vec3f& operator-=(const Vec3f& o) {
        x -= o.x, y -= o.y, z -= o.z;
        return *this;
    }
    constexpr Vec3f& operator*=(float s) {
        x *= s, y *= s, z *= s;
        return *this;
    }
    constexpr bool operator==(const Vec3f&) const = default;
};

[[nodiscard]] constexpr Vec3f operator+(Vec3f a, Vec3f b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
[[nodiscard]] constexpr Vec3f operator-(Vec3f a, Vec3f b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
[[nodiscard]] constexpr Vec3f operator-(Vec3f a) {
    return {-a.x, -a.y, -a.z};
}
[[nodiscard]] constexpr Vec3f operator*(Vec3f a, float s) {
    return {a.x * s, a.y * s, a.z * s};
}
[[nodiscard]] constexpr Vec3f operator*(float s, Vec3f a) {
    return a * s;
}
[[nodiscard]] constexpr Vec3f operator*(Vec3f a, Vec3f b) {
    return {a.x * b.x, a.y * b.y, a.z * b.z};
}
[[nodiscard]] constexpr Vec3f operator/(Vec3f a, float s) {
    return {a.x / s, a.y / s, a.z / s};
}

[[nodiscard]] constexpr float dot(Vec3f a, Vec3f b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
[[nodiscard]] constexpr Vec3f cross(Vec3f a, Vec3f b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
[[nodiscard]] inline float length(Vec3f a) {
    return std::sqrt(dot(a, a));
}
[[nodiscard]] inline Vec3f normalize(Vec3f a) {
    return a / length(a);
}
[[nodiscard]] constexpr Vec3f min(Vec3f a, Vec3f b) {
    return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
[[nodiscard]] constexpr Vec3f max(Vec3f a, Vec3f b) {
    return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
[[nodiscard]] inline Vec3f abs(Vec3f a) {
    return {std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)};
}
[[nodiscard]] constexpr float max_component(Vec3f a) {
    return std::max(a.x, std::max(a.y, a.z));
}
// The axis of the largest component, the first of equal ones: x if x >= y and x >= z, else y if y >= z, else
// z. By arithmetic on the comparisons, not branches: the watertight test takes the dominant axis of every
// ray's direction, random on incoherent rays, where branches mispredicted (docs/accel/stream.md).
[[nodiscard]] constexpr int max_axis(Vec3f a) {
    const int x_ge_y = a.x >= a.y, x_ge_z = a.x >= a.z, y_ge_z = a.y >= a.z;
    const int if_x_ge_y = (1 - x_ge_z) << 1, otherwise = 2 - y_ge_z;
    return otherwise ^ ((if_x_ge_y ^ otherwise) & -x_ge_y);
}
// The components as an array, for an index computed at run time: Vec3f::operator[]'s ternaries compile to
// branches, which mispredict where the index varies from ray to ray.
[[nodiscard]] constexpr std::array<float, 3> as_array(Vec3f a) {
    return {a.x, a.y, a.z};
}
// Whether `a` is neither infinite nor NaN (which fails both comparisons). By comparisons rather than
// std::isfinite, so that these and lancer/ray.hpp's is_valid are constexpr: nvcc compiles them for the
// device (--expt-relaxed-constexpr), and the GPU kernels test rays by these very functions.
[[nodiscard]] constexpr bool is_finite_number(float a) {
    return a >= -std::numeric_limits<float>::max() && a <= std::numeric_limits<float>::max();
}
[[nodiscard]] constexpr bool is_finite(Vec3f a) {
    return is_finite_number(a.x) && is_finite_number(a.y) && is_finite_number(a.z);
}

}  // namespace lancer
