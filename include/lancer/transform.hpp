// Affine maps of points and directions (row-major 3x4, Embree's RTC_FORMAT_FLOAT3X4_ROW_MAJOR): what places
// an instance (lancer/instances.hpp) and a scene graph's mesh (lancer/scene.hpp, MeshInstance).
#pragma once

#include "lancer/vec.hpp"

namespace lancer {

// 48 bytes: an affine map, row-major 3x4 (Embree's RTC_FORMAT_FLOAT3X4_ROW_MAJOR): a point p maps to
// (m[r][0] p.x + m[r][1] p.y + m[r][2] p.z + m[r][3]) on row r, a direction without the last column.
struct Transform {
    float m[3][4] = {{1.0f, 0.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f, 0.0f}};

    [[nodiscard]] static Transform translation(Vec3f offset);
    // The rotation by `radians` about `axis` (any non-zero length), right-handed.
    [[nodiscard]] static Transform rotation(Vec3f axis, float radians);
    [[nodiscard]] static Transform scaling(Vec3f factors);

    // In double, rounded to float once per component.
    [[nodiscard]] Vec3f point(Vec3f p) const;
    [[nodiscard]] Vec3f vector(Vec3f v) const;
    // The unit normal of a surface of normal `n` (any length) moved by the map: cof(A) n for the linear part
    // A, in double, normalised and rounded once; the zero vector for a zero n. cof(A) (u x v) is the cross
    // product of the moved vectors, so that a triangle's (v1 - v0) x (v2 - v0) moves to the moved triangle's,
    // a mirror turning it as it turns the vertices' order.
    [[nodiscard]] Vec3f normal(Vec3f n) const;
    bool operator==(const Transform&) const = default;
};
static_assert(sizeof(Transform) == 48);

// a after b (a * b applied to p is a(b(p))), in double, rounded to float once per entry.
[[nodiscard]] Transform operator*(const Transform& a, const Transform& b);

}  // namespace lancer
