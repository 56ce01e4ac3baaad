// The nearest point of a triangle or a sphere to a query point, in double and rounded once
// (GeometryQueries::nearest_point, docs/python.md), and the same for four triangles of a leaf block at once
// in AVX2 doubles: every lane does the scalar code's operations in its order (no fused multiply-add:
// -ffp-contract=off), so that both give the same bits, and walking bvh8's blocks answers what walking the
// binary BVH does.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include "accel/bvh/triangle_block.hpp"
#include "lancer/queries.hpp"
#include "lancer/scene.hpp"
#include "lancer/vec3d.hpp"

namespace lancer::nearest {

// The barycentric weights (of v1, v2) of the point of triangle `tri` nearest to p: the Voronoi regions of
// its vertices, then of its edges, then its face (Ericson, Real-Time Collision Detection, 5.1.5). A
// degenerate triangle falls in a vertex's or an edge's region; a zero denominator there means two equal
// vertices, and either end is nearest.
inline std::pair<double, double> nearest_weights(const Triangle& tri, const Vec3d& p) {
    const Vec3d a = Vec3d(tri.v0), b = Vec3d(tri.v1), c = Vec3d(tri.v2);
    const Vec3d ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return {0.0, 0.0};
    const Vec3d bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return {1.0, 0.0};
    const auto ratio = [](double n, double d) { return d == 0.0 ? 0.0 : n / d; };
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return {ratio(d1, d1 - d3), 0.0};
    const Vec3d cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return {0.0, 1.0};
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return {0.0, ratio(d2, d2 - d6)};
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
        const double w = ratio(d4 - d3, (d4 - d3) + (d5 - d6));
        return {1.0 - w, w};
    }
    const double sum = va + vb + vc;
    return {vb / sum, vc / sum};
}

// The nearest point of primitive `prim` to p in double, and a triangle's weights of it (0 for a sphere).
struct ExactNearest {
    Vec3d point;
    double u = 0.0, v = 0.0;
};
inline ExactNearest exact_nearest(const Geometry& geometry, std::uint32_t prim, const Vec3d& p) {
    if (prim < geometry.triangles.size()) {
        const Triangle& tri = geometry.triangles[prim];
        const auto [u, v] = nearest_weights(tri, p);
        const Vec3d a = Vec3d(tri.v0), b = Vec3d(tri.v1), c = Vec3d(tri.v2);
        return {{a.x + u * (b.x - a.x) + v * (c.x - a.x), a.y + u * (b.y - a.y) + v * (c.y - a.y),
                 a.z + u * (b.z - a.z) + v * (c.z - a.z)},
                u,
                v};
    }
    const Sphere& sphere = geometry.spheres[prim - geometry.triangles.size()];
    const Vec3d centre = Vec3d(sphere.center), d = p - centre;
    const double length = std::sqrt(dot(d, d));
    const double scale = length > 0.0 ? std::max(0.0, static_cast<double>(sphere.radius)) / length : 0.0;
    return {{centre.x + scale * d.x, centre.y + scale * d.y, centre.z + scale * d.z}};
}

// The nearest point of primitive `prim` to p, and its squared distance in double.
inline NearestPoint nearest_on(const Geometry& geometry, std::uint32_t prim, const Vec3d& p,
                               double& distance2) {
    const ExactNearest exact = exact_nearest(geometry, prim, p);
    const Vec3d e = p - exact.point;
    distance2 = dot(e, e);
    NearestPoint nearest;
    nearest.prim = static_cast<std::int32_t>(prim);
    nearest.point = {static_cast<float>(exact.point.x), static_cast<float>(exact.point.y),
                     static_cast<float>(exact.point.z)};
    nearest.distance = static_cast<float>(std::sqrt(distance2));
    nearest.u = static_cast<float>(exact.u), nearest.v = static_cast<float>(exact.v);
    return nearest;
}

// `found`, the nearest point to p of a geometry scaled by 2^-exponent, in the caller's units: its point and
// distance recomputed in double and scaled back before their one rounding, so that they are the unscaled
// geometry's bits (a power of two changes none in double), even where the scaled distance passes the float
// range and the caller's does not.
inline NearestPoint nearest_on_scaled(const Geometry& geometry, const NearestPoint& found, const Vec3d& p,
                                      int exponent) {
    const ExactNearest exact = exact_nearest(geometry, static_cast<std::uint32_t>(found.prim), p);
    const Vec3d e = p - exact.point;
    NearestPoint nearest = found;
    nearest.point = {static_cast<float>(std::ldexp(exact.point.x, exponent)),
                     static_cast<float>(std::ldexp(exact.point.y, exponent)),
                     static_cast<float>(std::ldexp(exact.point.z, exponent))};
    nearest.distance = static_cast<float>(std::ldexp(std::sqrt(dot(e, e)), exponent));
    return nearest;
}

// The best point so far of one query: a candidate replaces it when nearer, or as near with a smaller
// primitive index.
struct Search {
    const Geometry& geometry;
    Vec3d p;
    NearestPoint best;
    double best2 = std::numeric_limits<double>::infinity();

    Search(const Geometry& g, const Vec3d& point) : geometry(g), p(point) {}

    void consider(const NearestPoint& candidate, double distance2) {
        if (distance2 < best2 || (distance2 == best2 && candidate.prim < best.prim))
            best = candidate, best2 = distance2;
    }
    void primitive(std::uint32_t prim) {
        double distance2;
        const NearestPoint candidate = nearest_on(geometry, prim, p, distance2);
        consider(candidate, distance2);
    }
    // best2 as a float no smaller, at most the largest float, so that a box bound (child_bounds) compared in
    // float prunes no box that the double comparison would keep, and never keeps an empty slot.
    [[nodiscard]] float float_limit() const {
        const float limit = static_cast<float>(std::min(best2, double(std::numeric_limits<float>::max())));
        return static_cast<double>(limit) >= best2 ? limit : std::nextafter(limit, kInfinity);
    }
    template <int K>
    void block(const TriangleBlock<K>& block);
};

#if defined(__AVX2__)
namespace detail {

struct Vec3d4 {
    __m256d x, y, z;
};
inline Vec3d4 sub(const Vec3d4& a, const Vec3d4& b) {
    return {_mm256_sub_pd(a.x, b.x), _mm256_sub_pd(a.y, b.y), _mm256_sub_pd(a.z, b.z)};
}
inline __m256d dot(const Vec3d4& a, const Vec3d4& b) {
    return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(a.x, b.x), _mm256_mul_pd(a.y, b.y)),
                         _mm256_mul_pd(a.z, b.z));
}
template <int K>
inline Vec3d4 corner(const TriangleBlock<K>& block, int v, int first) {
    return {_mm256_cvtps_pd(_mm_loadu_ps(&block.vertex[v][0][first])),
            _mm256_cvtps_pd(_mm_loadu_ps(&block.vertex[v][1][first])),
            _mm256_cvtps_pd(_mm_loadu_ps(&block.vertex[v][2][first]))};
}
inline __m256d le(__m256d a, __m256d b) {
    return _mm256_cmp_pd(a, b, _CMP_LE_OQ);
}
inline __m256d ge(__m256d a, __m256d b) {
    return _mm256_cmp_pd(a, b, _CMP_GE_OQ);
}
inline __m256d all3(__m256d a, __m256d b, __m256d c) {
    return _mm256_and_pd(_mm256_and_pd(a, b), c);
}
// nearest_weights's ratio: 0 where the denominator is 0.
inline __m256d ratio(__m256d n, __m256d d) {
    const __m256d zero = _mm256_setzero_pd();
    return _mm256_blendv_pd(_mm256_div_pd(n, d), zero, _mm256_cmp_pd(d, zero, _CMP_EQ_OQ));
}

// nearest_weights and nearest_on's point on lanes [first, first + 4) of a block: every region's weights
// computed in every lane, then the first region that holds chosen, as the scalar code's order of tests.
// Lanes without a triangle (NaN vertices) come out NaN, which no comparison accepts.
struct FourNearest {
    alignas(32) double u[4], v[4], x[4], y[4], z[4], distance2[4];

    template <int K>
    FourNearest(const TriangleBlock<K>& block, int first, const Vec3d& point) {
        const Vec3d4 p = {_mm256_set1_pd(point.x), _mm256_set1_pd(point.y), _mm256_set1_pd(point.z)};
        const Vec3d4 a = corner(block, 0, first), b = corner(block, 1, first), c = corner(block, 2, first);
        const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
        const Vec3d4 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a), bp = sub(p, b), cp = sub(p, c);
        const __m256d d1 = dot(ab, ap), d2 = dot(ac, ap), d3 = dot(ab, bp), d4 = dot(ac, bp);
        const __m256d d5 = dot(ab, cp), d6 = dot(ac, cp);
        const __m256d vc = _mm256_sub_pd(_mm256_mul_pd(d1, d4), _mm256_mul_pd(d3, d2));
        const __m256d vb = _mm256_sub_pd(_mm256_mul_pd(d5, d2), _mm256_mul_pd(d1, d6));
        const __m256d va = _mm256_sub_pd(_mm256_mul_pd(d3, d6), _mm256_mul_pd(d5, d4));
        const __m256d d43 = _mm256_sub_pd(d4, d3), d56 = _mm256_sub_pd(d5, d6);
        // From the face's region back to the first vertex's, each region overriding the ones tested after it.
        const __m256d sum = _mm256_add_pd(_mm256_add_pd(va, vb), vc);
        __m256d weight_u = _mm256_div_pd(vb, sum), weight_v = _mm256_div_pd(vc, sum);
        const __m256d edge_bc = all3(le(va, zero), ge(d43, zero), ge(d56, zero));
        const __m256d w = ratio(d43, _mm256_add_pd(d43, d56));
        weight_u = _mm256_blendv_pd(weight_u, _mm256_sub_pd(one, w), edge_bc),
        weight_v = _mm256_blendv_pd(weight_v, w, edge_bc);
        const __m256d edge_ac = all3(le(vb, zero), ge(d2, zero), le(d6, zero));
        weight_u = _mm256_blendv_pd(weight_u, zero, edge_ac),
        weight_v = _mm256_blendv_pd(weight_v, ratio(d2, _mm256_sub_pd(d2, d6)), edge_ac);
        const __m256d vertex_c = _mm256_and_pd(ge(d6, zero), le(d5, d6));
        weight_u = _mm256_blendv_pd(weight_u, zero, vertex_c),
        weight_v = _mm256_blendv_pd(weight_v, one, vertex_c);
        const __m256d edge_ab = all3(le(vc, zero), ge(d1, zero), le(d3, zero));
        weight_u = _mm256_blendv_pd(weight_u, ratio(d1, _mm256_sub_pd(d1, d3)), edge_ab),
        weight_v = _mm256_blendv_pd(weight_v, zero, edge_ab);
        const __m256d vertex_b = _mm256_and_pd(ge(d3, zero), le(d4, d3));
        weight_u = _mm256_blendv_pd(weight_u, one, vertex_b),
        weight_v = _mm256_blendv_pd(weight_v, zero, vertex_b);
        const __m256d vertex_a = _mm256_and_pd(le(d1, zero), le(d2, zero));
        weight_u = _mm256_blendv_pd(weight_u, zero, vertex_a),
        weight_v = _mm256_blendv_pd(weight_v, zero, vertex_a);
        // nearest_on's point a + weight_u (b - a) + weight_v (c - a) and its squared distance.
        const Vec3d4 q = {
            _mm256_add_pd(_mm256_add_pd(a.x, _mm256_mul_pd(weight_u, ab.x)), _mm256_mul_pd(weight_v, ac.x)),
            _mm256_add_pd(_mm256_add_pd(a.y, _mm256_mul_pd(weight_u, ab.y)), _mm256_mul_pd(weight_v, ac.y)),
            _mm256_add_pd(_mm256_add_pd(a.z, _mm256_mul_pd(weight_u, ab.z)), _mm256_mul_pd(weight_v, ac.z))};
        const Vec3d4 e = sub(p, q);
        _mm256_store_pd(u, weight_u), _mm256_store_pd(v, weight_v);
        _mm256_store_pd(x, q.x), _mm256_store_pd(y, q.y), _mm256_store_pd(z, q.z);
        _mm256_store_pd(distance2, dot(e, e));
    }
};

}  // namespace detail
#endif

template <int K>
void Search::block(const TriangleBlock<K>& block) {
#if defined(__AVX2__)
    static_assert(K % 4 == 0);
    for (int first = 0; first < K; first += 4) {
        const detail::FourNearest four(block, first, p);
        for (int k = 0; k < 4; ++k) {
            const std::uint32_t prim = block.prim[first + k];
            if (prim >= geometry.triangles.size()) {
                if (prim != TriangleBlock<K>::kNoPrimitive) primitive(prim);  // a sphere
                continue;
            }
            if (!(four.distance2[k] <= best2)) continue;
            NearestPoint candidate;
            candidate.prim = static_cast<std::int32_t>(prim);
            candidate.point = {static_cast<float>(four.x[k]), static_cast<float>(four.y[k]),
                               static_cast<float>(four.z[k])};
            candidate.distance = static_cast<float>(std::sqrt(four.distance2[k]));
            candidate.u = static_cast<float>(four.u[k]), candidate.v = static_cast<float>(four.v[k]);
            consider(candidate, four.distance2[k]);
        }
    }
#else
    for (int lane = 0; lane < K; ++lane) {
        if (block.prim[lane] != TriangleBlock<K>::kNoPrimitive) primitive(block.prim[lane]);
    }
#endif
}

}  // namespace lancer::nearest
