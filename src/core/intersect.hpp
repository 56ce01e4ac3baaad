// Ray-primitive kernels: slab test, Moller-Trumbore, watertight triangle, sphere, plane.
// Every kernel accepts a hit only for t in [tnear, tfar] (docs/numerical-contract.md) and rejects NaN
// intermediate values by writing each acceptance test so that a NaN comparison fails it. The two triangle
// tests are host-device (LANCER_HOST_DEVICE): the GPU kernels call this one source (cuda/triangle.hpp).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "core/exact_sign.hpp"
#include "core/host_device.hpp"
#include "core/isa_namespace.hpp"
#include "lancer/box.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"
#include "lancer/vec3d.hpp"

namespace lancer {
// Per instruction set (core/isa_namespace.hpp): the kernels compiled for AVX-512 call these too.
inline namespace LANCER_ISA_NAMESPACE {

// Bound on the relative rounding error of n chained fp32 operations (pbrt-v4, section 6.8.1).
[[nodiscard]] constexpr float gamma_bound(int n) {
    constexpr float half_ulp = std::numeric_limits<float>::epsilon() * 0.5f;
    return (static_cast<float>(n) * half_ulp) / (1.0f - static_cast<float>(n) * half_ulp);
}

// ---------------------------------------------------------------------------------------------------------
// Slab test (Kay & Kajiya 1986; the "Lancer de rayon" slides, "boîtes englobantes").
// The reciprocal direction of a zero component is +-inf; when the origin also lies on that slab's plane
// the product is 0 * inf = NaN. The ray then runs inside the plane of a face, within the closed slab, so
// that slab is unbounded: boxes are closed, and a ray along a face never loses the box.
struct SlabRay {
    Vec3f origin;
    Vec3f inv_direction;

    LANCER_HOST_DEVICE explicit SlabRay(const Ray& ray)
        : origin(ray.origin),
          inv_direction(1.0f / ray.direction.x, 1.0f / ray.direction.y, 1.0f / ray.direction.z) {}
};

// A slab's exit distance moved away from the entry by 2 gamma(3) of its magnitude (pbrt-v4,
// Bounds3::IntersectP), towards +inf whatever its sign: multiplying a negative distance by 1 + 2 gamma(3)
// would shrink the interval, and a valid ray with tnear < 0 then lost a box it crosses within rounding
// (fuzz/rays_fuzz.cpp, docs/robustness.md).
inline constexpr float kSlabExitGrow = 1.0f + 2.0f * gamma_bound(3);
inline constexpr float kSlabExitShrink = 1.0f - 2.0f * gamma_bound(3);
[[nodiscard]] LANCER_HOST_DEVICE inline float widened_slab_exit(float t) {
    return t * (t > 0.0f ? kSlabExitGrow : kSlabExitShrink);
}

// On success [t_entry, t_exit] is the part of [tnear, tfar] inside the box, t_exit widened
// (widened_slab_exit) so that rounding never misses a box whose face a hit lies on.
[[nodiscard]] LANCER_HOST_DEVICE inline bool intersect_box(const SlabRay& ray, const Box3f& box, float tnear,
                                                           float tfar, float& t_entry, float& t_exit) {
    float t0 = tnear, t1 = tfar;
    for (int axis = 0; axis < 3; ++axis) {
        float near_plane = (box.lo[axis] - ray.origin[axis]) * ray.inv_direction[axis];
        float far_plane = (box.hi[axis] - ray.origin[axis]) * ray.inv_direction[axis];
        float slab_near = min_of(near_plane, far_plane);
        float slab_far = widened_slab_exit(max_of(near_plane, far_plane));
        if (is_nan(near_plane) || is_nan(far_plane)) slab_near = -kInfinity, slab_far = kInfinity;
        t0 = max_of(t0, slab_near);
        t1 = min_of(t1, slab_far);
    }
    t_entry = t0, t_exit = t1;
    return t0 <= t1;
}

// ---------------------------------------------------------------------------------------------------------
struct TriangleHit {
    float t = 0.0f, u = 0.0f, v = 0.0f;
};

// Moller & Trumbore 1997, as written in Ferreira & Mendoza 2011, section 3:
// [t u v] = 1 / ((D x E2) . E1) [((T x E1) . E2), ((D x E2) . T), ((T x E1) . D)], T = O - V0.
struct MollerTrumbore {
    // |det| <= 2^-20 |d| |e1| |e2| (max norms): a miss (parallel ray, degenerate triangle).
    static constexpr float kIllConditioned = 0x1p-20f;
    // |det| <= 2^-8 |d| |e1| |e2|: the grazing band, decided in double (intersect_in_double). The ratio of
    // the two bands is a power of two, so the second is the first scaled exactly.
    static constexpr float kGrazingBand = 0x1p-8f;
    static constexpr float kGrazingScale = kGrazingBand / kIllConditioned;
    // The float u and v err by at most 2^7 2^-24 S |d| |e2| / |det| and 2^7 2^-24 S |d| |e1| / |det|, with
    // S = |T| + |e1| + |e2| (max norms). Forward error: T, e1 and e2 are rounded once each, the cross
    // products' components carry 6 2^-24 |d| |e2| and 6 2^-24 |T| |e1|, the dot products 3 2^-24 of the sum
    // of their terms, about 42 2^-24 |T| |d| |e2| for u det and 42 2^-24 |e1| |d| |e2| for det, whose error
    // moves u by u times its relative error; 2^7 covers the sum and the last roundings (the e1 and e2 terms
    // keep the slack above 2^-19.6, beyond the 2^-24 of rounding u, v and u + v).
    static constexpr float kRoundingSlack = 0x1p-17f;

    struct RayData {
        Vec3f origin, direction;
        float direction_scale;  // max |d_i|
        LANCER_HOST_DEVICE explicit RayData(const Ray& ray)
            : origin(ray.origin),
              direction(ray.direction),
              direction_scale(max_component(magnitude(ray.direction))) {}
    };

    [[nodiscard]] LANCER_HOST_DEVICE static bool intersect(const RayData& ray, const Triangle& tri,
                                                           float tnear, float tfar, TriangleHit& out) {
        const Vec3f e1 = tri.v1 - tri.v0;
        const Vec3f e2 = tri.v2 - tri.v0;
        const Vec3f p = cross(ray.direction, e2);
        const float det = dot(p, e1);
        // det = d . (e1 x e2): zero for a ray parallel to the plane or a degenerate triangle. Near zero, u, v
        // and t are mostly rounding noise (a zero-area triangle would report hits far from its segment), so
        // the ill-conditioned band |det| < 2^-20 |d| |e1| |e2| (max norms, about 1e-6 rad of grazing angle
        // times the triangle's own angle) is a miss too.
        // A det beyond the float range (edges whose product passes 2^127) makes inv_det 0 and u = v = t = 0:
        // a hit at the origin whatever the triangle. It is a miss.
        const float e1_scale = max_component(magnitude(e1)), e2_scale = max_component(magnitude(e2));
        const float band = kIllConditioned * ray.direction_scale * e1_scale * e2_scale;
        if (!(magnitude(det) > band && magnitude(det) < kInfinity)) return false;
        const float inv_det = 1.0f / det;
        const Vec3f to_origin = ray.origin - tri.v0;
        // The float u and v decide only where they are farther from the triangle's edges than their error
        // bound (kRoundingSlack); within it the double test decides (a filtered predicate). Decided in float
        // up to the edges, a hit could lie farther from the exact line than the geometric tolerance by which
        // the structures grow their boxes, and brute force would report triangles that every structure culls.
        // The screens are widened by the same bound, so that they never drop a hit the double test would
        // find; the double test decides before any test that depends on [tnear, tfar], so that a structure
        // that passes a shorter tfar than brute force still gets the same answer. A grazing ray (|det| within
        // 2^12 of the ill-conditioned band) always goes to double: its float t errs by up to
        // 2^-24 |T| |d| |e1| |e2| / |det| too, a 65536th of |T| at the band and without bound towards the
        // first band. docs/numerical-contract.md, "Triangle tests".
        const bool grazing = magnitude(det) <= band * kGrazingScale;
        const float slack = kRoundingSlack * ray.direction_scale *
                            (max_component(magnitude(to_origin)) + e1_scale + e2_scale) * magnitude(inv_det);
        const float slack_u = slack * e2_scale, slack_v = slack * e1_scale;
        const float u = dot(to_origin, p) * inv_det;
        if (!(u >= -slack_u && u <= 1.0f + slack_u)) return false;
        const Vec3f q = cross(to_origin, e1);
        const float v = dot(ray.direction, q) * inv_det;
        if (!(v >= -slack_v && u + v <= 1.0f + (slack_u + slack_v))) return false;
        const bool certain = u >= slack_u && v >= slack_v && u + v <= 1.0f - (slack_u + slack_v);
        if (grazing || !certain) return intersect_in_double(ray, tri, tnear, tfar, out);
        const float t = dot(e2, q) * inv_det;
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;  // an overflowed t is no hit
        out = {t, u, v};
        return true;
    }

    // The same formula in double, on the float inputs (exact in double): its 2^-53 rounding leaves t, u and
    // v within about 2^-33 |T| even at the first band.
    [[nodiscard]] LANCER_HOST_DEVICE static bool intersect_in_double(const RayData& ray, const Triangle& tri,
                                                                     float tnear, float tfar,
                                                                     TriangleHit& out) {
        const Vec3d v0(tri.v0), direction(ray.direction);
        const Vec3d e1 = Vec3d(tri.v1) - v0, e2 = Vec3d(tri.v2) - v0;
        const Vec3d p = cross(direction, e2);
        const double det = dot(p, e1);
        if (det == 0.0) return false;
        const double inv_det = 1.0 / det;
        const Vec3d to_origin = Vec3d(ray.origin) - v0;
        const double u = dot(to_origin, p) * inv_det;
        if (!(u >= 0.0 && u <= 1.0)) return false;
        const Vec3d q = cross(to_origin, e1);
        const double v = dot(direction, q) * inv_det;
        if (!(v >= 0.0 && u + v <= 1.0)) return false;
        const auto t = static_cast<float>(dot(e2, q) * inv_det);
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;
        out = {t, static_cast<float>(u), static_cast<float>(v)};
        return true;
    }
};

// Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection", JCGT 2013. The vertices are moved into a
// ray space where the ray is the +z axis through the origin; the 2D edge functions of a shared edge are then
// evaluated from the same two transformed vertices by both triangles.
//
// The transformed vertices are rounded, though, and an edge function exact for them can have the wrong sign
// for the exact line: a ray grazing a triangle whose projection is thinner than that rounding was missed
// whatever its barycentrics. So each edge function is a filtered predicate: beyond its error bound
// (kEdgeSlack) the float sign is the exact line's; within it the sign is computed exactly
// (line_edge_side, core/exact_sign.hpp). Either way every edge gets the exact sign, which the neighbour
// across it gets too, so the test stays watertight and answers what exact arithmetic would. The bound is at
// least FLT_MIN, so zero and denormal edge functions (section 3.1 of the paper; a product in the denormal
// range keeps only an absolute precision of 2^-150) are decided exactly too. A hit whose numerator
// T = sum w z falls below 2^-100 is computed in double: its products may have underflowed, and t = T / det,
// with det as small as FLT_MIN, could then be wrong by up to 2^-24 (docs/numerical-contract.md, "Triangle
// tests"). Above 2^-100 some product exceeds 2^-102, whose own float rounding dwarfs the 2^-150 that
// underflow may cost the others.
//
// Each edge function is a difference of products computed by Kahan's algorithm (difference_of_products,
// core/host_device.hpp), within 2 2^-24 of its own magnitude. With two rounded products, as the paper
// writes it, an edge function errs by up to 2^-24 N^2 however small it is, and t = T / det, which weighs
// the vertices' depths by the edge functions, moved by that times the depths' spread over det: on a long
// thin triangle crossed at a grazing angle the hit left the triangle's box (docs/robustness.md, finding 35).
// Relative errors of 2 2^-24 in the weights keep t within 2 2^-24 of the spread from the moved triangle's.
struct Watertight {
    // The axes {kx, ky, kz} of a ray whose direction is dominant along kz: kx and ky the next two in cyclic
    // order, swapped when the dominant component is negative, to keep the winding. The packet kernels
    // (bvh/bvh8_packet.cpp) choose per lane from the same table.
    // By arithmetic, not a choice between two arrays, which compiled to a branch on the ray's sign.
    [[nodiscard]] static constexpr std::array<int, 3> permutation(int kz, bool negative) {
        const int next = (kz + 1) & -static_cast<int>(kz != 2),
                  last = (next + 1) & -static_cast<int>(next != 2);
        const int swapped = (next ^ last) & -static_cast<int>(negative);
        return {next ^ swapped, last ^ swapped, kz};
    }

    struct RayData {
        Vec3f origin, direction;  // the direction for the exact signs of line_edge_side
        int kx, ky, kz;           // kz: the dominant axis of the direction
        float shear_x, shear_y, shear_z;

        // Without branches (max_axis, permutation and as_array's indexing): on incoherent rays the dominant
        // axis and its sign are random, and branches mispredicted at every ray (docs/accel/stream.md).
        LANCER_HOST_DEVICE explicit RayData(const Ray& ray) : origin(ray.origin), direction(ray.direction) {
            kz = max_axis(magnitude(ray.direction));
            const std::array<float, 3> components = as_array(ray.direction);
            const std::array<int, 3> axes = permutation(kz, components[kz] < 0.0f);
            kx = axes[0], ky = axes[1];
            shear_x = components[kx] / components[kz];
            shear_y = components[ky] / components[kz];
            shear_z = 1.0f / components[kz];
        }
    };

    // The float edge functions err from those of the exact line and vertices by at most
    // 16 2^-24 N (N + Z), N the largest |x| or |y| of the three sheared vertices and Z their largest |z|:
    // each sheared x or y is within 2 2^-24 N + 4 2^-24 Z of its exact value (the translation, the shear
    // factor d[kx] / d[kz] of magnitude at most 1, its product and the difference rounded once each), which
    // the two products carry into 8 2^-24 N^2 + 16 2^-24 N Z, and Kahan's difference adds 2 2^-24 |w|, at
    // most 4 2^-24 N^2. kEdgeSlack is twice that bound's constant, which also covers the bound's own
    // rounding (docs/numerical-contract.md, "Triangle tests"). A power of two, so the scaling is exact, and
    // the vector kernels compute the same bound.
    static constexpr float kEdgeSlack = 0x1p-19f;
    // Below this |T| the float products of T may have underflowed (see above); the vector kernels hand such
    // lanes to this scalar kernel.
    static constexpr float kSmallNumerator = 0x1p-100f;

    [[nodiscard]] LANCER_HOST_DEVICE static bool intersect(const RayData& ray, const Triangle& tri,
                                                           float tnear, float tfar, TriangleHit& out) {
        const Sheared v = sheared(ray, tri);
        const float w0 = difference_of_products(v.bx, v.cy, v.by, v.cx);
        const float w1 = difference_of_products(v.cx, v.ay, v.cy, v.ax);
        const float w2 = difference_of_products(v.ax, v.by, v.ay, v.bx);
        // Products that overflowed (vertices far beyond the contract's 2^60 domain) make an edge function
        // NaN: a miss, as in the vector kernels, where a NaN lane's t is NaN.
        if (is_nan(w0) || is_nan(w1) || is_nan(w2)) return false;
        const float slack = edge_slack(v);
        const bool certain0 = magnitude(w0) > slack, certain1 = magnitude(w1) > slack,
                   certain2 = magnitude(w2) > slack;
        // Two certain edge functions of opposite signs: a miss, decided before any exact sign is computed.
        if (((certain0 && w0 < 0.0f) || (certain1 && w1 < 0.0f) || (certain2 && w2 < 0.0f)) &&
            ((certain0 && w0 > 0.0f) || (certain1 && w1 > 0.0f) || (certain2 && w2 > 0.0f)))
            return false;
        if (!(certain0 && certain1 && certain2)) {
            if (!(is_finite(tri.v0) && is_finite(tri.v1) && is_finite(tri.v2))) return false;
            // A certain edge function's sign is the exact one already.
            auto sign = [](float w) { return w > 0.0f ? 1 : -1; };
            const int side0 = certain0 ? sign(w0) : line_edge_side(ray.origin, ray.direction, tri.v1, tri.v2);
            const int side1 = certain1 ? sign(w1) : line_edge_side(ray.origin, ray.direction, tri.v2, tri.v0);
            const int side2 = certain2 ? sign(w2) : line_edge_side(ray.origin, ray.direction, tri.v0, tri.v1);
            return intersect_exactly(ray, tri, side0, side1, side2, tnear, tfar, out);
        }
        // Three certain edge functions of one sign, each above FLT_MIN: det is not zero.
        const float det = w0 + w1 + w2;
        const float az = ray.shear_z * v.az, bz = ray.shear_z * v.bz, cz = ray.shear_z * v.cz;
        const float numerator = w0 * az + w1 * bz + w2 * cz;
        if (magnitude(numerator) < kSmallNumerator) return intersect_in_double(ray, v, tnear, tfar, out);
        const float inv_det = 1.0f / det;
        const float t = numerator * inv_det;
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;  // an overflowed t is no hit
        out = {t, w1 * inv_det, w2 * inv_det};
        return true;
    }

  private:
    // The vertices relative to the origin, (x, y) sheared into ray space, z along the dominant axis (not yet
    // scaled by shear_z = 1 / d[kz]).
    struct Sheared {
        float ax, ay, az, bx, by, bz, cx, cy, cz;
    };
    LANCER_HOST_DEVICE static Sheared sheared(const RayData& ray, const Triangle& tri) {
        const Vec3f a = tri.v0 - ray.origin;
        const Vec3f b = tri.v1 - ray.origin;
        const Vec3f c = tri.v2 - ray.origin;
        return {a[ray.kx] - ray.shear_x * a[ray.kz], a[ray.ky] - ray.shear_y * a[ray.kz], a[ray.kz],
                b[ray.kx] - ray.shear_x * b[ray.kz], b[ray.ky] - ray.shear_y * b[ray.kz], b[ray.kz],
                c[ray.kx] - ray.shear_x * c[ray.kz], c[ray.ky] - ray.shear_y * c[ray.kz], c[ray.kz]};
    }

    // kEdgeSlack's bound, N and Z as maxima and the products in this order, as the vector kernels compute it;
    // at least FLT_MIN.
    LANCER_HOST_DEVICE static float edge_slack(const Sheared& v) {
        const float planar =
            max_of(max_of(max_of(magnitude(v.ax), magnitude(v.ay)), max_of(magnitude(v.bx), magnitude(v.by))),
                   max_of(magnitude(v.cx), magnitude(v.cy)));
        const float depth = max_of(max_of(magnitude(v.az), magnitude(v.bz)), magnitude(v.cz));
        return max_of((planar + depth) * planar * kEdgeSlack, std::numeric_limits<float>::min());
    }

    // The same test from the same sheared floats, in double, for a hit whose float numerator may have
    // underflowed: det, T, t, u and v free of underflow, rounded to float once. The edge functions were
    // certain, so their double signs are the float ones.
    LANCER_HOST_DEVICE static bool intersect_in_double(const RayData& ray, const Sheared& v, float tnear,
                                                       float tfar, TriangleHit& out) {
        const double w0 = double(v.bx) * v.cy - double(v.by) * v.cx;
        const double w1 = double(v.cx) * v.ay - double(v.cy) * v.ax;
        const double w2 = double(v.ax) * v.by - double(v.ay) * v.bx;
        const double det = w0 + w1 + w2;
        const double shear_z = ray.shear_z;  // z * shear_z exact in double: no underflow there either
        const auto t =
            static_cast<float>((w0 * (shear_z * v.az) + w1 * (shear_z * v.bz) + w2 * (shear_z * v.cz)) / det);
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;
        out = {t, static_cast<float>(w1 / det), static_cast<float>(w2 / det)};
        return true;
    }

    // The hit where the exact signs put it on an edge (one zero sign), (t, u, v) in double: where the line
    // meets the edge's line p + s e. o + t d = p + s e gives t = ((p - o) x e) . (d x e) / |d x e|^2 and
    // s = ((p - o) x d) . (d x e) / |d x e|^2, conditioned by the angle between the two lines however near
    // the line runs to the triangle's plane.
    struct ExactHit {
        double t, u, v;
    };
    LANCER_HOST_DEVICE static ExactHit on_edge(const RayData& ray, const Triangle& tri, int side0,
                                               int side1) {
        // Side k is the edge opposite vertex k, from vertex k + 1 to vertex k + 2.
        const Vec3f& from = side0 == 0 ? tri.v1 : (side1 == 0 ? tri.v2 : tri.v0);
        const Vec3f& to = side0 == 0 ? tri.v2 : (side1 == 0 ? tri.v0 : tri.v1);
        const Vec3d edge = Vec3d(to) - Vec3d(from), direction(ray.direction);
        const Vec3d to_edge = Vec3d(from) - Vec3d(ray.origin);
        const Vec3d across = cross(direction, edge);
        const double length2 = dot(across, across);
        const double t = dot(cross(to_edge, edge), across) / length2;
        const double along = dot(cross(to_edge, direction), across) / length2;
        const double s = along > 1.0 ? 1.0 : (along > 0.0 ? along : 0.0);  // on the edge, as the signs say
        if (side0 == 0) return {t, 1.0 - s, s};
        return side1 == 0 ? ExactHit{t, 0.0, 1.0 - s} : ExactHit{t, s, 0.0};
    }

    // The hit on a vertex (two zero signs: its depth) or inside (none), (t, u, v) in double, from the
    // vertices sheared into ray space: (x, y), and the depth z / d[kz], the vertex at origin + depth *
    // direction when it lies on the line.
    LANCER_HOST_DEVICE static ExactHit on_vertex_or_inside(const RayData& ray, const Triangle& tri, int side0,
                                                           int side1, int side2) {
        const std::array<float, 3> d = as_array(ray.direction);
        const double shear_x = double(d[ray.kx]) / d[ray.kz], shear_y = double(d[ray.ky]) / d[ray.kz];
        struct RaySpace {
            double x, y, depth;
        };
        auto to_ray_space = [&](const Vec3f& vertex) {
            const Vec3d relative = Vec3d(vertex) - Vec3d(ray.origin);
            const std::array<double, 3> r = {relative.x, relative.y, relative.z};
            return RaySpace{r[ray.kx] - shear_x * r[ray.kz], r[ray.ky] - shear_y * r[ray.kz],
                            r[ray.kz] / d[ray.kz]};
        };
        if (side1 == 0 && side2 == 0) return {to_ray_space(tri.v0).depth, 0.0, 0.0};
        if (side0 == 0 && side2 == 0) return {to_ray_space(tri.v1).depth, 1.0, 0.0};
        if (side0 == 0 && side1 == 0) return {to_ray_space(tri.v2).depth, 0.0, 1.0};
        const RaySpace a = to_ray_space(tri.v0), b = to_ray_space(tri.v1), c = to_ray_space(tri.v2);
        // An edge function whose double sign differs from the exact one is rounding noise around zero.
        auto clamped = [](double w, int side) {
            return (w > 0.0 && side > 0) || (w < 0.0 && side < 0) ? w : 0.0;
        };
        const double e0 = clamped(b.x * c.y - b.y * c.x, side0), e1 = clamped(c.x * a.y - c.y * a.x, side1),
                     e2 = clamped(a.x * b.y - a.y * b.x, side2);
        const double det = e0 + e1 + e2;
        if (det != 0.0) return {(e0 * a.depth + e1 * b.depth + e2 * c.depth) / det, e1 / det, e2 / det};
        // Every weight vanished in double: the plane's t, and each corner its share.
        const Vec3d v0(tri.v0);
        const Vec3d normal = cross(Vec3d(tri.v1) - v0, Vec3d(tri.v2) - v0);
        return {dot(normal, v0 - Vec3d(ray.origin)) / dot(normal, Vec3d(ray.direction)), 1.0 / 3.0,
                1.0 / 3.0};
    }

    // A ray within the slack of an edge, from the exact signs of its three edge functions: they decide, and
    // they place the hit. On an edge it is on_edge's; on a vertex, t is the vertex's depth; inside, the edge
    // functions, recomputed in double from vertices sheared in double and clamped to those signs, weigh the
    // vertices' depths into t, a convex combination on the triangle however the weights round. The plane's t
    // divides two cancellations on a grazing line and can land anywhere on it; it serves only where every
    // weight vanishes in double, and a denominator that rounds to zero then gives no hit
    // (docs/numerical-contract.md, "Triangle tests"). t, u and v are rounded to float once.
    LANCER_HOST_DEVICE static bool intersect_exactly(const RayData& ray, const Triangle& tri, int side0,
                                                     int side1, int side2, float tnear, float tfar,
                                                     TriangleHit& out) {
        if ((side0 < 0 || side1 < 0 || side2 < 0) && (side0 > 0 || side1 > 0 || side2 > 0)) return false;
        // Three zeros: the line lies in the triangle's plane, or the triangle is degenerate.
        if (side0 == 0 && side1 == 0 && side2 == 0) return false;
        const int zeros =
            static_cast<int>(side0 == 0) + static_cast<int>(side1 == 0) + static_cast<int>(side2 == 0);
        const ExactHit hit =
            zeros == 1 ? on_edge(ray, tri, side0, side1) : on_vertex_or_inside(ray, tri, side0, side1, side2);
        const auto t = static_cast<float>(hit.t);
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;
        out = {t, static_cast<float>(hit.u), static_cast<float>(hit.v)};
        return true;
    }
};

// ---------------------------------------------------------------------------------------------------------
// Ray-sphere (the "Lancer de rayon" slides): t^2 d.d + 2t d.(o - c) + |o - c|^2 - r^2 = 0, solved with the
// discriminant of Haines et al., "Precision Improvements for Ray/Sphere Intersection" (Ray Tracing Gems, ch.
// 7), which stays accurate far from the sphere, and the stable root pair q / a, c / q. The nearer root in
// [tnear, tfar] wins; the far one answers rays that start inside. (u, v) = (azimuth / 2pi, polar / pi).
// In double: the squares of float lengths neither underflow nor overflow there, where in float a tiny radius
// and a ray's tiny distance from the sphere both square to 0 and the discriminant says tangent
// (docs/numerical-contract.md, "Spheres"). Spheres are tested one at a time (scalar lanes), so double costs
// little.
[[nodiscard]] inline bool intersect_sphere(const Ray& ray, const Sphere& sphere, float tnear, float tfar,
                                           TriangleHit& out) {
    if (!(sphere.radius > 0.0f)) return false;
    const Vec3d direction(ray.direction);
    const Vec3d f = Vec3d(ray.origin) - Vec3d(sphere.center);
    const double a = dot(direction, direction);
    const double half_b = dot(f, direction);
    const Vec3d closest_offset = f - (half_b / a) * direction;
    const double r2 = double(sphere.radius) * sphere.radius;
    const double discriminant = a * (r2 - dot(closest_offset, closest_offset));
    if (!(discriminant >= 0.0)) return false;
    const double c = dot(f, f) - r2;
    const double q = -(half_b + std::copysign(std::sqrt(discriminant), half_b));
    auto t_near_root = static_cast<float>(c / q), t_far_root = static_cast<float>(q / a);
    if (t_near_root > t_far_root) std::swap(t_near_root, t_far_root);
    float t;
    if (t_near_root >= tnear && t_near_root <= tfar && t_near_root < kInfinity) {
        t = t_near_root;
    } else if (t_far_root >= tnear && t_far_root <= tfar && t_far_root < kInfinity) {
        t = t_far_root;
    } else {
        return false;  // also rejects the NaN of c / q when q == 0 (ray from the centre, tangent)
    }
    const Vec3d local = f + double(t) * direction;
    const double azimuth = std::atan2(local.y, local.x);
    const double polar = std::acos(std::clamp(local.z / sphere.radius, -1.0, 1.0));
    out = {t,
           static_cast<float>((azimuth < 0.0 ? azimuth + 2.0 * std::numbers::pi : azimuth) /
                              (2.0 * std::numbers::pi)),
           static_cast<float>(polar / std::numbers::pi)};
    return true;
}

// ---------------------------------------------------------------------------------------------------------
// Ray-plane, t = (D - o.n) / (d.n), with the four cases of the "Lancer de rayon" slides.
enum class PlaneCase {
    Parallel,  // d.n = 0 and the origin off the plane: t infinite, no hit
    InPlane,   // d.n = 0 and the origin on the plane: t undefined, counted as no hit
    Behind,    // t < tnear: the plane is behind the ray's start
    Ahead,     // t >= tnear: the plane is in front (a hit when t <= tfar too)
};

[[nodiscard]] inline PlaneCase classify_plane(const Ray& ray, const Plane& plane, float tnear, float& t) {
    const float denominator = dot(ray.direction, plane.normal);
    const float numerator = plane.offset - dot(ray.origin, plane.normal);
    if (denominator == 0.0f) return numerator == 0.0f ? PlaneCase::InPlane : PlaneCase::Parallel;
    t = numerator / denominator;
    return t >= tnear ? PlaneCase::Ahead : PlaneCase::Behind;
}

[[nodiscard]] inline bool intersect_plane(const Ray& ray, const Plane& plane, float tnear, float tfar,
                                          float& t) {
    return classify_plane(ray, plane, tnear, t) == PlaneCase::Ahead && t <= tfar;
}

}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
