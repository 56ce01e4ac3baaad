// The box the binned builder's bins, its spatial splits and its small subtrees extend: Box3f's boxes and
// areas, bit for bit, in SIMD rows.
#pragma once

#include <cstddef>

#include "accel/build_util.hpp"
#include "accel/bvh/build_common.hpp"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace lancer {

// A box as two 4-float rows (the fourth lane unused), so that extending one is one vector min and one
// vector max: binning extends a bin's box three times per reference. Default construction leaves it
// uninitialised, so that a node's Bins clear only the bins it uses; `none()` is the empty box.
struct BinBox {
#if defined(__SSE2__)
    __m128 lo, hi;

    [[nodiscard]] static BinBox none() {
        return {_mm_set1_ps(kInfinity), _mm_set1_ps(-kInfinity)};
    }

    // A reference's box: the loads read lo.xyz and hi.x, then hi.xyz and centroid.x, all inside the
    // BuildRef; the fourth lane is never read back.
    [[nodiscard]] static BinBox of(const BuildRef& ref) {
        static_assert(offsetof(BuildRef, bounds) == 0 && offsetof(BuildRef, centroid) == sizeof(Box3f));
        return {_mm_loadu_ps(&ref.bounds.lo.x), _mm_loadu_ps(&ref.bounds.hi.x)};
    }
    // A centroid: the load reads x, y, z and the BuildRef's next field.
    [[nodiscard]] static BinBox of_point(const Vec3f& centroid) {
        static_assert(offsetof(BuildRef, prim) == offsetof(BuildRef, centroid) + sizeof(Vec3f));
        const __m128 point = _mm_loadu_ps(&centroid.x);
        return {point, point};
    }
    [[nodiscard]] static BinBox of_box(const Box3f& box) {
        return {_mm_setr_ps(box.lo.x, box.lo.y, box.lo.z, 0.0f),
                _mm_setr_ps(box.hi.x, box.hi.y, box.hi.z, 0.0f)};
    }
    [[nodiscard]] static BinBox of_vertex(const Vec3f& point) {
        const __m128 row = _mm_setr_ps(point.x, point.y, point.z, 0.0f);
        return {row, row};
    }
    void extend(const BinBox& other) {
        lo = _mm_min_ps(other.lo, lo), hi = _mm_max_ps(other.hi, hi);
    }
    void clip(const BinBox& other) {
        lo = _mm_max_ps(other.lo, lo), hi = _mm_min_ps(other.hi, hi);
    }
    // Extends `if_true` by `other` where `which`, `if_false` otherwise, without a branch (a partition's sides
    // are close to random): the other box is extended by the empty box, which leaves it as it was.
    static void extend_either(BinBox& if_true, BinBox& if_false, const BinBox& other, bool which) {
        const __m128 mask = _mm_castsi128_ps(_mm_set1_epi32(-static_cast<int>(which)));
        const BinBox empty = none();
        if_true.extend({select(mask, other.lo, empty.lo), select(mask, other.hi, empty.hi)});
        if_false.extend({select(mask, empty.lo, other.lo), select(mask, empty.hi, other.hi)});
    }
    // As Box3f::empty: lo > hi, or a NaN, on some axis.
    [[nodiscard]] bool empty() const {
        return (_mm_movemask_ps(_mm_cmpnle_ps(lo, hi)) & 0b111) != 0;
    }
    // Box3f::surface_area in the same fp32 operations, (xy + yz) + zx, without leaving the registers.
    [[nodiscard]] float area() const {
        if (empty()) return 0.0f;
        return filled_area();
    }
    // area() of a box known to bound something, without the check: the sweeps' boxes, which each hold a
    // reference at least, and the bins', whose empty ones are never weighed (their count is zero).
    [[nodiscard]] float filled_area() const {
        const __m128 e = _mm_sub_ps(hi, lo);
        const __m128 products = _mm_mul_ps(e, _mm_shuffle_ps(e, e, _MM_SHUFFLE(3, 0, 2, 1)));
        const __m128 sum = _mm_add_ss(_mm_add_ss(products, _mm_shuffle_ps(products, products, 1)),
                                      _mm_movehl_ps(products, products));
        return 2.0f * _mm_cvtss_f32(sum);
    }
    // Per lane, `if_set` where `mask` is set, else `if_clear`.
    [[nodiscard]] static __m128 select(__m128 mask, __m128 if_set, __m128 if_clear) {
#if defined(__SSE4_1__)
        return _mm_blendv_ps(if_clear, if_set, mask);
#else
        return _mm_or_ps(_mm_and_ps(mask, if_set), _mm_andnot_ps(mask, if_clear));
#endif
    }
    [[nodiscard]] Box3f box() const {
        alignas(16) float low[4], high[4];
        _mm_store_ps(low, lo), _mm_store_ps(high, hi);
        return {{low[0], low[1], low[2]}, {high[0], high[1], high[2]}};
    }
#else
    Box3f bounds;

    [[nodiscard]] static BinBox none() {
        return {};
    }
    [[nodiscard]] static BinBox of(const BuildRef& ref) {
        return {ref.bounds};
    }
    [[nodiscard]] static BinBox of_point(const Vec3f& centroid) {
        return {{centroid, centroid}};
    }
    [[nodiscard]] static BinBox of_box(const Box3f& box) {
        return {box};
    }
    [[nodiscard]] static BinBox of_vertex(const Vec3f& point) {
        return {{point, point}};
    }
    void extend(const BinBox& other) {
        bounds.extend(other.bounds);
    }
    void clip(const BinBox& other) {
        bounds = intersection(bounds, other.bounds);
    }
    static void extend_either(BinBox& if_true, BinBox& if_false, const BinBox& other, bool which) {
        (which ? if_true : if_false).extend(other);
    }
    [[nodiscard]] bool empty() const {
        return bounds.empty();
    }
    [[nodiscard]] float area() const {
        return bounds.surface_area();
    }
    [[nodiscard]] float filled_area() const {
        return bounds.surface_area();
    }
    [[nodiscard]] Box3f box() const {
        return bounds;
    }
#endif
};

}  // namespace lancer
