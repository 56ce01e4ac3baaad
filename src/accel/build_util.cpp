#include "accel/build_util.hpp"

#include "core/parallel.hpp"
#include "core/ray_conditioning.hpp"

#include <array>
#include <cmath>

namespace lancer {

Box3f grown_for_overlap(const Box3f& box) {
    const Vec3f magnitude = max(abs(box.lo), abs(box.hi));
    const Vec3f margin = 1e-6f * (box.extent() + magnitude) + Vec3f(1e-30f);
    return {box.lo - margin, box.hi + margin};
}

float geometric_tolerance(const Box3f& scene_bounds) {
    if (scene_bounds.empty()) return 0.0f;
    const float largest_coordinate =
        std::max(max_component(abs(scene_bounds.lo)), max_component(abs(scene_bounds.hi)));
    return 0x1p-20f * largest_coordinate + kKernelTolerance * max_component(scene_bounds.extent());
}

namespace {

// Primitives per task of scale_geometry.
constexpr std::size_t kScaleGrain = 1 << 15;

Vec3f scaled_point(Vec3f p, int exponent) {
    return {std::ldexp(p.x, exponent), std::ldexp(p.y, exponent), std::ldexp(p.z, exponent)};
}

}  // namespace

Box3f hit_bounds(const Geometry& geometry) {
    Box3f box;
    for (const Triangle& t : geometry.triangles)
        box.extend(t.bounds());
    for (const Sphere& sphere : geometry.spheres) {
        if (sphere.radius > 0.0f) box.extend(sphere.bounds());
    }
    return box;
}

Box3f scale_geometry(const Geometry& geometry, int exponent, std::vector<Triangle>& triangles,
                     std::vector<Sphere>& spheres) {
    triangles.resize(geometry.triangles.size());
    spheres.resize(geometry.spheres.size());
    parallel::for_each_chunk(0, triangles.size(), kScaleGrain, [&](std::size_t from, std::size_t to) {
        for (std::size_t i = from; i < to; ++i) {
            const Triangle& t = geometry.triangles[i];
            triangles[i] = {scaled_point(t.v0, exponent), scaled_point(t.v1, exponent),
                            scaled_point(t.v2, exponent)};
        }
    });
    for (std::size_t i = 0; i < spheres.size(); ++i) {
        const Sphere& sphere = geometry.spheres[i];
        spheres[i] = {scaled_point(sphere.center, exponent), std::ldexp(sphere.radius, exponent),
                      sphere.material};
    }
    // The box as the structures compute it, a sphere's rounded at the new scale.
    return hit_bounds({triangles, spheres});
}

namespace {

// Akenine-Moller, "Fast 3D Triangle-Box Overlap Testing" (2001): the 13 candidate separating axes are the
// three box normals, the triangle normal and the nine cross products of box and triangle edges.
bool triangle_overlaps_box(const Triangle& tri, const Box3f& box) {
    const Vec3f center = box.center();
    const Vec3f half = box.extent() * 0.5f;
    const std::array<Vec3f, 3> v = {tri.v0 - center, tri.v1 - center, tri.v2 - center};
    const std::array<Vec3f, 3> edges = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
    auto separated_on = [&](Vec3f axis) {
        const float p0 = dot(v[0], axis), p1 = dot(v[1], axis), p2 = dot(v[2], axis);
        const float radius =
            half.x * std::fabs(axis.x) + half.y * std::fabs(axis.y) + half.z * std::fabs(axis.z);
        return std::min({p0, p1, p2}) > radius || std::max({p0, p1, p2}) < -radius;
    };
    for (int axis = 0; axis < 3; ++axis) {
        Vec3f unit(0.0f);
        unit[axis] = 1.0f;
        if (separated_on(unit)) return false;
    }
    for (const Vec3f& edge : edges) {
        for (int axis = 0; axis < 3; ++axis) {
            Vec3f unit(0.0f);
            unit[axis] = 1.0f;
            if (separated_on(cross(unit, edge))) return false;
        }
    }
    return !separated_on(cross(edges[0], edges[1]));
}

// Distance test of Arvo (1990): squared distance from the centre to the box against r^2.
bool sphere_overlaps_box(const Sphere& sphere, const Box3f& box) {
    float distance2 = 0.0f;
    for (int axis = 0; axis < 3; ++axis) {
        const float c = sphere.center[axis];
        const float d = c < box.lo[axis] ? box.lo[axis] - c : (c > box.hi[axis] ? c - box.hi[axis] : 0.0f);
        distance2 += d * d;
    }
    return distance2 <= sphere.radius * sphere.radius;
}

// Sutherland-Hodgman: a triangle clipped by six planes has at most 3 + 6 vertices.
Box3f clip_triangle(const Triangle& tri, const Box3f& box) {
    std::array<Vec3f, 9> polygon = {tri.v0, tri.v1, tri.v2};
    std::array<Vec3f, 9> clipped{};
    int count = 3;
    for (int axis = 0; axis < 3 && count > 0; ++axis) {
        for (int side = 0; side < 2 && count > 0; ++side) {
            const float plane = side == 0 ? box.lo[axis] : box.hi[axis];
            // Signed distance, positive inside.
            auto inside_distance = [&](const Vec3f& p) {
                return side == 0 ? p[axis] - plane : plane - p[axis];
            };
            int out = 0;
            for (int i = 0; i < count; ++i) {
                const Vec3f& a = polygon[static_cast<std::size_t>(i)];
                const Vec3f& b = polygon[static_cast<std::size_t>((i + 1) % count)];
                const float da = inside_distance(a), db = inside_distance(b);
                if (da >= 0.0f) clipped[static_cast<std::size_t>(out++)] = a;
                if ((da >= 0.0f) != (db >= 0.0f)) {
                    Vec3f crossing = a + (da / (da - db)) * (b - a);
                    crossing[axis] = plane;  // exactly on the plane, whatever the rounding
                    clipped[static_cast<std::size_t>(out++)] = crossing;
                }
            }
            polygon = clipped;
            count = out;
        }
    }
    Box3f result;
    for (int i = 0; i < count; ++i)
        result.extend(polygon[static_cast<std::size_t>(i)]);
    return result;
}

}  // namespace

bool primitive_overlaps_box(const Geometry& geometry, std::uint32_t prim, const Box3f& box) {
    const Box3f grown = grown_for_overlap(box);
    if (prim < geometry.triangles.size()) return triangle_overlaps_box(geometry.triangles[prim], grown);
    return sphere_overlaps_box(geometry.spheres[prim - geometry.triangles.size()], grown);
}

Box3f clipped_primitive_bounds(const Geometry& geometry, std::uint32_t prim, const Box3f& box) {
    if (prim >= geometry.triangles.size()) return intersection(primitive_bounds(geometry, prim), box);
    Box3f clipped = clip_triangle(geometry.triangles[prim], grown_for_overlap(box));
    return clipped.empty() ? clipped : intersection(clipped, box);
}

}  // namespace lancer
