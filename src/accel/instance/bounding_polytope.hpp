// The points whose mapped box is an instance's world box (docs/accel/instances.md, "Instance boxes"): the
// corners of a 26-sided polytope around an object's primitives, a 26-DOP (the slabs of Kay & Kajiya, 1986,
// along 13 directions), computed once per object and mapped at every move of an instance.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "lancer/box.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"
#include "lancer/vec3d.hpp"

namespace lancer::top_level {

// The slabs' directions: every vector of components in {-1, 0, 1} whose first non-zero component is 1 (the
// 3 axes, the 6 face diagonals and the 4 body diagonals): half of the 3^3 - 1 non-zero ones.
inline constexpr int kSlabDirections = (3 * 3 * 3 - 1) / 2;
inline constexpr int kPolytopePlanes = 2 * kSlabDirections;  // each slab's two planes

// The planes' outward normals: the slabs' directions, then their opposites in the same order.
inline std::vector<Vec3d> polytope_normals() {
    std::vector<Vec3d> normals;
    for (int x = 1; x >= -1; --x) {
        for (int y = 1; y >= -1; --y) {
            for (int z = 1; z >= -1; --z) {
                const int first = x != 0 ? x : (y != 0 ? y : z);
                if (first == 1) normals.emplace_back(x, y, z);
            }
        }
    }
    for (int k = 0; k < kSlabDirections; ++k)
        normals.push_back(-1.0 * normals[static_cast<std::size_t>(k)]);
    return normals;
}

// The corners of that polytope around `geometry`, which a structure holds scaled by 2^scale_exponent
// (Accel::built_geometry), in the object's unscaled frame. Each slab of direction n is grown by `tolerance`
// |n|_1: the hits the object reports lie within `tolerance` of its primitives on each coordinate. For every
// direction u, the largest u . p over the corners is then at least the largest over the primitives grown so.
// Empty when the geometry has no primitive; the caller then keeps its box's corners.
inline std::vector<Vec3d> bounding_polytope(const Geometry& geometry, int scale_exponent, const Box3f& bounds,
                                            double tolerance) {
    const std::vector<Vec3d> normal = polytope_normals();
    std::array<double, kPolytopePlanes> length{}, offset{};  // plane k: normal[k] . x <= offset[k]
    for (int k = 0; k < kPolytopePlanes; ++k) {
        length[k] = std::sqrt(dot(normal[k], normal[k]));
        offset[k] = -kInfinity;
    }
    const double unscale = std::ldexp(1.0, -scale_exponent);  // a power of two: exact
    auto extend = [&](const Vec3f& point, double radius) {
        const Vec3d p = unscale * Vec3d(point);
        for (int k = 0; k < kSlabDirections; ++k) {
            const double along = dot(normal[k], p), reach = unscale * radius * length[k];
            offset[k] = std::max(offset[k], along + reach);
            offset[k + kSlabDirections] = std::max(offset[k + kSlabDirections], reach - along);
        }
    };
    for (const Triangle& triangle : geometry.triangles) {
        for (const Vec3f* vertex : {&triangle.v0, &triangle.v1, &triangle.v2})
            extend(*vertex, 0.0);
    }
    for (const Sphere& sphere : geometry.spheres)
        extend(sphere.center, sphere.radius);
    if (!std::isfinite(offset[0])) return {};
    // The slack, far above the rounding of the offsets and of the corners solved below (double) and far
    // below the tolerance (float), keeps the corners outside the grown primitives.
    const double slack = 0x1p-36 * (max_component(max(abs(bounds.lo), abs(bounds.hi))) + tolerance);
    for (int k = 0; k < kPolytopePlanes; ++k) {
        const Vec3d& n = normal[k];
        offset[k] += tolerance * (std::fabs(n.x) + std::fabs(n.y) + std::fabs(n.z)) + slack;
    }
    // The corners: where three planes meet and no plane excludes the point. A corner where more than three
    // planes meet comes from each of their triples and is kept once, since every update maps each point.
    std::vector<Vec3d> corners;
    auto add_corner = [&](int a, int b, int c) {
        const Vec3d bc = cross(normal[b], normal[c]), ca = cross(normal[c], normal[a]),
                    ab = cross(normal[a], normal[b]);
        const double determinant = dot(normal[a], bc);
        if (std::fabs(determinant) < 0.5) return;  // integer normals: 0 or at least 1 in magnitude
        const Vec3d point = (1.0 / determinant) * (offset[a] * bc + offset[b] * ca + offset[c] * ab);
        for (int k = 0; k < kPolytopePlanes; ++k) {
            if (dot(normal[k], point) > offset[k] + slack) return;
        }
        auto same = [&](const Vec3d& kept) {
            return std::fabs(kept.x - point.x) <= slack && std::fabs(kept.y - point.y) <= slack &&
                   std::fabs(kept.z - point.z) <= slack;
        };
        if (std::none_of(corners.begin(), corners.end(), same)) corners.push_back(point);
    };
    for (int a = 0; a < kPolytopePlanes; ++a) {
        for (int b = a + 1; b < kPolytopePlanes; ++b) {
            for (int c = b + 1; c < kPolytopePlanes; ++c)
                add_corner(a, b, c);
        }
    }
    return corners;
}

}  // namespace lancer::top_level
