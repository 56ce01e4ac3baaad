// Thin wrappers over SSE and AVX2 float vectors, so that the wide BVH's box test and the triangle block
// tests read like their scalar kernels (Embree's vfloat<N>, without its machinery). Chosen at compile time
// by __SSE4_1__ / __AVX2__ (the project builds with -march=native, LANCER_NATIVE); the callers keep a scalar
// path for builds without them.
//
// Numerics: every operation is the IEEE fp32 operation of the scalar code (division is divps, never the
// rcpps estimate), and -ffp-contract=off keeps GCC from fusing the vector multiplies and adds, as in the
// scalar kernels. Comparisons are ordered and quiet: a NaN compares false, as in C++.
#pragma once

#if defined(__AVX2__) || defined(__SSE4_1__)
#include <immintrin.h>
#endif

namespace lancer::simd {

#if defined(__SSE4_1__)
struct Sse4 {
    using Float = __m128;
    static constexpr int kWidth = 4;

    static Float broadcast(float x) { return _mm_set1_ps(x); }
    static Float load(const float* p) { return _mm_load_ps(p); }
    static void store(float* p, Float x) { _mm_storeu_ps(p, x); }
    static Float add(Float a, Float b) { return _mm_add_ps(a, b); }
    static Float sub(Float a, Float b) { return _mm_sub_ps(a, b); }
    static Float mul(Float a, Float b) { return _mm_mul_ps(a, b); }
    static Float div(Float a, Float b) { return _mm_div_ps(a, b); }
    // maxps(a, b) and minps(a, b) return b when either operand is NaN.
    static Float max(Float a, Float b) { return _mm_max_ps(a, b); }
    static Float min(Float a, Float b) { return _mm_min_ps(a, b); }
    // fabs: clears the sign bit.
    static Float abs(Float a) { return _mm_andnot_ps(_mm_set1_ps(-0.0f), a); }
    static Float less(Float a, Float b) { return _mm_cmplt_ps(a, b); }
    static Float less_equal(Float a, Float b) { return _mm_cmple_ps(a, b); }
    static Float greater(Float a, Float b) { return _mm_cmpgt_ps(a, b); }
    static Float greater_equal(Float a, Float b) { return _mm_cmpge_ps(a, b); }
    static Float equal(Float a, Float b) { return _mm_cmpeq_ps(a, b); }
    static Float bit_and(Float a, Float b) { return _mm_and_ps(a, b); }
    static Float bit_or(Float a, Float b) { return _mm_or_ps(a, b); }
    static Float bit_xor(Float a, Float b) { return _mm_xor_ps(a, b); }
    // a > b ? if_greater : otherwise, per lane (ordered: a NaN lane takes `otherwise`, as the scalar
    // ternary).
    static Float select_if_greater(Float a, Float b, Float if_greater, Float otherwise) {
        return _mm_blendv_ps(otherwise, if_greater, _mm_cmpgt_ps(a, b));
    }
    static unsigned mask(Float a) { return static_cast<unsigned>(_mm_movemask_ps(a)); }
};
#endif

#if defined(__AVX2__)
struct Avx2 {
    using Float = __m256;
    static constexpr int kWidth = 8;

    static Float broadcast(float x) { return _mm256_set1_ps(x); }
    static Float load(const float* p) { return _mm256_load_ps(p); }
    static void store(float* p, Float x) { _mm256_storeu_ps(p, x); }
    static Float add(Float a, Float b) { return _mm256_add_ps(a, b); }
    static Float sub(Float a, Float b) { return _mm256_sub_ps(a, b); }
    static Float mul(Float a, Float b) { return _mm256_mul_ps(a, b); }
    static Float div(Float a, Float b) { return _mm256_div_ps(a, b); }
    static Float max(Float a, Float b) { return _mm256_max_ps(a, b); }
    static Float min(Float a, Float b) { return _mm256_min_ps(a, b); }
    static Float abs(Float a) { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), a); }
    static Float less(Float a, Float b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
    static Float less_equal(Float a, Float b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
    static Float greater(Float a, Float b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
    static Float greater_equal(Float a, Float b) { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); }
    static Float equal(Float a, Float b) { return _mm256_cmp_ps(a, b, _CMP_EQ_OQ); }
    static Float bit_and(Float a, Float b) { return _mm256_and_ps(a, b); }
    static Float bit_or(Float a, Float b) { return _mm256_or_ps(a, b); }
    static Float bit_xor(Float a, Float b) { return _mm256_xor_ps(a, b); }
    static Float select_if_greater(Float a, Float b, Float if_greater, Float otherwise) {
        return _mm256_blendv_ps(otherwise, if_greater, _mm256_cmp_ps(a, b, _CMP_GT_OQ));
    }
    static unsigned mask(Float a) { return static_cast<unsigned>(_mm256_movemask_ps(a)); }
};
#endif

}  // namespace lancer::simd
