// Double-precision vectors: the kernels' exact fallbacks (grazing Moller-Trumbore, spheres), the tests'
// reference computations and the Python module's camera frames. A float converts to double exactly, and so
// does a product of two floats.
#pragma once

#include <cmath>

#include "lancer/vec.hpp"

namespace lancer {

struct Vec3d {
    double x, y, z;
    constexpr Vec3d(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    constexpr explicit Vec3d(const Vec3f& v) : x(v.x), y(v.y), z(v.z) {}
};
[[nodiscard]] constexpr Vec3d operator+(const Vec3d& a, const Vec3d& b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
[[nodiscard]] constexpr Vec3d operator-(const Vec3d& a, const Vec3d& b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
[[nodiscard]] constexpr Vec3d operator*(double s, const Vec3d& a) {
    return {s * a.x, s * a.y, s * a.z};
}
[[nodiscard]] constexpr double dot(const Vec3d& a, const Vec3d& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
[[nodiscard]] constexpr Vec3d cross(const Vec3d& a, const Vec3d& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
[[nodiscard]] inline Vec3d normalize(const Vec3d& a) {
    const double length = std::sqrt(dot(a, a));
    return {a.x / length, a.y / length, a.z / length};
}

}  // namespace lancer
