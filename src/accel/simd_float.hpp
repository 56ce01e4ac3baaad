// Thin wrappers over SSE, AVX2 and AVX-512 float vectors, so that the wide BVH's box test and the triangle
// tests read like their scalar kernels (Embree's vfloat<N> and vbool<N>, without its machinery), chosen at
// compile time (docs/isa.md). Every operation is the scalar code's IEEE fp32 operation (division by divps,
// never the rcpps estimate; a fused multiply-add only where the scalar code fuses explicitly,
// difference_of_products of core/host_device.hpp), so both paths give the same bits
// (docs/accel/bvh_wide.md). A comparison returns a Mask (all-ones lanes for SSE and AVX2, a k-register for
// AVX-512), ordered and quiet as in C++ (a NaN compares false); mask_and / mask_or combine masks, bits()
// gives bit i for lane i.
#pragma once

#if defined(__AVX512F__) || defined(__AVX2__) || defined(__SSE4_1__)
#include <immintrin.h>
#endif

#include "core/host_device.hpp"
#include "core/isa_namespace.hpp"

// An inline namespace per instruction set (core/isa_namespace.hpp): every template on these types, the
// triangle block and box tests among them, then differs by name between an AVX2 and an AVX-512 compilation.
namespace lancer::simd {
inline namespace LANCER_ISA_NAMESPACE {

#if defined(__SSE4_1__)
struct Sse4 {
    using Float = __m128;
    using Mask = __m128;
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
    static Mask mask_and(Mask a, Mask b) { return _mm_and_ps(a, b); }
    static Mask mask_or(Mask a, Mask b) { return _mm_or_ps(a, b); }
    static unsigned bits(Mask a) { return static_cast<unsigned>(_mm_movemask_ps(a)); }
    // The sign bit of every lane.
    static unsigned sign_bits(Float a) { return static_cast<unsigned>(_mm_movemask_ps(a)); }
    // max(|a|, |b|): one vrangeps where AVX-512 VL and DQ are compiled for (imm 0b1011: the larger
    // magnitude, its sign bit cleared).
    static Float max_magnitude(Float a, Float b) {
#if defined(__AVX512VL__) && defined(__AVX512DQ__)
        return _mm_range_ps(a, b, 0b1011);
#else
        return max(abs(a), abs(b));
#endif
    }
    // a b - c d as difference_of_products (core/host_device.hpp) computes it.
    // An SSE 4.1 machine without FMA (a native build below the AVX2 baseline) fuses lane by lane.
    static Float difference_of_products(Float a, Float b, Float c, Float d) {
#if defined(__FMA__)
        const Float cd = mul(c, d);
        return add(_mm_fmsub_ps(a, b, cd), _mm_fnmadd_ps(c, d, cd));
#else
        alignas(16) float lanes[4][4];
        _mm_store_ps(lanes[0], a), _mm_store_ps(lanes[1], b);
        _mm_store_ps(lanes[2], c), _mm_store_ps(lanes[3], d);
        for (int i = 0; i < 4; ++i)
            lanes[0][i] = lancer::difference_of_products(lanes[0][i], lanes[1][i], lanes[2][i], lanes[3][i]);
        return _mm_load_ps(lanes[0]);
#endif
    }
};
#endif

#if defined(__AVX2__)
struct Avx2 {
    using Float = __m256;
    using Mask = __m256;
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
    // if_true where the mask is set, else if_false.
    static Float select(Mask mask, Float if_true, Float if_false) {
        return _mm256_blendv_ps(if_false, if_true, mask);
    }
    // The 8 fields of 8 consecutive 32-byte records (Ray: ox oy oz dx dy dz tnear tfar): field[f] lane i is
    // record i's field f. An 8 x 8 transpose in registers (unpack, shuffle, swap of 128-bit halves).
    static void load_fields8(const float* p, Float (&field)[8]) {
        __m256 row[8];
        for (int i = 0; i < 8; ++i)
            row[i] = _mm256_loadu_ps(p + 8 * i);
        transpose8(row, field);
    }
    // field[f] lane i = row[i] lane f.
    static void transpose8(const Float (&row)[8], Float (&field)[8]) {
        __m256 quad[8];
        for (int half = 0; half < 2; ++half) {  // records 0-3, then 4-7
            const __m256* r = row + 4 * half;
            const __m256 t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
            const __m256 t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
            // quad[4 half + k]: field k of the four records in the low half, field k + 4 in the high one.
            quad[4 * half + 0] = _mm256_shuffle_ps(t0, t2, 0x44);
            quad[4 * half + 1] = _mm256_shuffle_ps(t0, t2, 0xee);
            quad[4 * half + 2] = _mm256_shuffle_ps(t1, t3, 0x44);
            quad[4 * half + 3] = _mm256_shuffle_ps(t1, t3, 0xee);
        }
        for (int k = 0; k < 4; ++k) {
            field[k] = _mm256_permute2f128_ps(quad[k], quad[4 + k], 0x20);
            field[k + 4] = _mm256_permute2f128_ps(quad[k], quad[4 + k], 0x31);
        }
    }
    // Integers carried in float lanes, bit for bit (a primitive index beside its hit's t).
    static Float broadcast_int(int x) { return _mm256_castsi256_ps(_mm256_set1_epi32(x)); }
    static Mask less_int(Float a, Float b) {
        return _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_castps_si256(b), _mm256_castps_si256(a)));
    }
    static Mask equal_int(Float a, Float b) {
        return _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_castps_si256(a), _mm256_castps_si256(b)));
    }
    // The mask whose lane i is set where bit i is.
    static Mask mask_from_bits(unsigned bits) {
        const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        return _mm256_castsi256_ps(_mm256_cmpeq_epi32(
            _mm256_and_si256(_mm256_set1_epi32(static_cast<int>(bits)), lane_bit), lane_bit));
    }
    // The smallest and the largest lane (no NaN lanes).
    static float reduce_min(Float a) {
        const __m128 half = _mm_min_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
        const __m128 pair = _mm_min_ps(half, _mm_movehl_ps(half, half));
        return _mm_cvtss_f32(_mm_min_ss(pair, _mm_shuffle_ps(pair, pair, 1)));
    }
    static float reduce_max(Float a) {
        const __m128 half = _mm_max_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
        const __m128 pair = _mm_max_ps(half, _mm_movehl_ps(half, half));
        return _mm_cvtss_f32(_mm_max_ss(pair, _mm_shuffle_ps(pair, pair, 1)));
    }
    // Writes a0 b0 c0 d0 a1 b1 c1 d1 ...: four fields of 8 consecutive 16-byte records (unaligned).
    static void store_interleaved(float* p, Float a, Float b, Float c, Float d) {
        const __m256 ab_low = _mm256_unpacklo_ps(a, b), ab_high = _mm256_unpackhi_ps(a, b);
        const __m256 cd_low = _mm256_unpacklo_ps(c, d), cd_high = _mm256_unpackhi_ps(c, d);
        // Records k and k + 4 of each 128-bit half, k = 0..3.
        const __m256 r0 =
            _mm256_castpd_ps(_mm256_unpacklo_pd(_mm256_castps_pd(ab_low), _mm256_castps_pd(cd_low)));
        const __m256 r1 =
            _mm256_castpd_ps(_mm256_unpackhi_pd(_mm256_castps_pd(ab_low), _mm256_castps_pd(cd_low)));
        const __m256 r2 =
            _mm256_castpd_ps(_mm256_unpacklo_pd(_mm256_castps_pd(ab_high), _mm256_castps_pd(cd_high)));
        const __m256 r3 =
            _mm256_castpd_ps(_mm256_unpackhi_pd(_mm256_castps_pd(ab_high), _mm256_castps_pd(cd_high)));
        _mm256_storeu_ps(p, _mm256_permute2f128_ps(r0, r1, 0x20));
        _mm256_storeu_ps(p + 8, _mm256_permute2f128_ps(r2, r3, 0x20));
        _mm256_storeu_ps(p + 16, _mm256_permute2f128_ps(r0, r1, 0x31));
        _mm256_storeu_ps(p + 24, _mm256_permute2f128_ps(r2, r3, 0x31));
    }
    static Mask mask_and(Mask a, Mask b) { return _mm256_and_ps(a, b); }
    static Mask mask_or(Mask a, Mask b) { return _mm256_or_ps(a, b); }
    static unsigned bits(Mask a) { return static_cast<unsigned>(_mm256_movemask_ps(a)); }
    static unsigned sign_bits(Float a) { return static_cast<unsigned>(_mm256_movemask_ps(a)); }
    // max(|a|, |b|), as Sse4's.
    static Float max_magnitude(Float a, Float b) {
#if defined(__AVX512VL__) && defined(__AVX512DQ__)
        return _mm256_range_ps(a, b, 0b1011);
#else
        return max(abs(a), abs(b));
#endif
    }
    // a b - c d as difference_of_products (core/host_device.hpp) computes it; AVX2 machines have FMA.
    static Float difference_of_products(Float a, Float b, Float c, Float d) {
        const Float cd = mul(c, d);
        return add(_mm256_fmsub_ps(a, b, cd), _mm256_fnmadd_ps(c, d, cd));
    }
};
#endif

#if defined(__AVX512F__) && defined(__AVX512DQ__)
struct Avx512 {
    using Float = __m512;
    using Mask = __mmask16;
    static constexpr int kWidth = 16;

    static Float broadcast(float x) { return _mm512_set1_ps(x); }
    static Float load(const float* p) { return _mm512_load_ps(p); }
    static void store(float* p, Float x) { _mm512_storeu_ps(p, x); }
    static Float add(Float a, Float b) { return _mm512_add_ps(a, b); }
    static Float sub(Float a, Float b) { return _mm512_sub_ps(a, b); }
    static Float mul(Float a, Float b) { return _mm512_mul_ps(a, b); }
    static Float div(Float a, Float b) { return _mm512_div_ps(a, b); }
    // vmaxps / vminps keep the SSE rule: the second operand when either is NaN. The zero-masked forms with
    // every lane set are the same instruction; GCC 12's _mm512_max_ps reads an uninitialised
    // _mm512_undefined_ps(), which -Werror=uninitialized rejects.
    static Float max(Float a, Float b) { return _mm512_maskz_max_ps(0xffff, a, b); }
    static Float min(Float a, Float b) { return _mm512_maskz_min_ps(0xffff, a, b); }
    static Float abs(Float a) { return _mm512_abs_ps(a); }
    // max(|a|, |b|), as Sse4's.
    static Float max_magnitude(Float a, Float b) { return _mm512_range_ps(a, b, 0b1011); }
    // a b - c d as difference_of_products (core/host_device.hpp) computes it.
    static Float difference_of_products(Float a, Float b, Float c, Float d) {
        const Float cd = mul(c, d);
        return add(_mm512_fmsub_ps(a, b, cd), _mm512_fnmadd_ps(c, d, cd));
    }
    static Mask less(Float a, Float b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
    static Mask less_equal(Float a, Float b) { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
    static Mask greater(Float a, Float b) { return _mm512_cmp_ps_mask(a, b, _CMP_GT_OQ); }
    static Mask greater_equal(Float a, Float b) { return _mm512_cmp_ps_mask(a, b, _CMP_GE_OQ); }
    static Mask equal(Float a, Float b) { return _mm512_cmp_ps_mask(a, b, _CMP_EQ_OQ); }
    static Float bit_and(Float a, Float b) { return _mm512_and_ps(a, b); }
    static Float bit_or(Float a, Float b) { return _mm512_or_ps(a, b); }
    static Float bit_xor(Float a, Float b) { return _mm512_xor_ps(a, b); }
    static Float select_if_greater(Float a, Float b, Float if_greater, Float otherwise) {
        return _mm512_mask_blend_ps(_mm512_cmp_ps_mask(a, b, _CMP_GT_OQ), otherwise, if_greater);
    }
    static Float select(Mask mask, Float if_true, Float if_false) {
        return _mm512_mask_blend_ps(mask, if_false, if_true);
    }
    // The 8 fields of 16 consecutive 32-byte records, field[f] lane i being record i's field f: three rounds
    // of two-source permutes, 24 in all.
    static void load_fields8(const float* p, Float (&field)[8]) {
        // Round 1: fields 0-3 (low) and 4-7 (high) of records 4j .. 4j + 3, record-major.
        const __m512i low_fields =
            _mm512_setr_epi32(0, 1, 2, 3, 8, 9, 10, 11, 16, 17, 18, 19, 24, 25, 26, 27);
        const __m512i high_fields =
            _mm512_setr_epi32(4, 5, 6, 7, 12, 13, 14, 15, 20, 21, 22, 23, 28, 29, 30, 31);
        __m512 low[4], high[4];
        for (int j = 0; j < 4; ++j) {
            const __m512 first = _mm512_loadu_ps(p + 32 * j), second = _mm512_loadu_ps(p + 32 * j + 16);
            low[j] = _mm512_permutex2var_ps(first, low_fields, second);
            high[j] = _mm512_permutex2var_ps(first, high_fields, second);
        }
        // Round 2: of records 8h .. 8h + 7, fields 2m and 2m + 1 (of the four in low or high), field-major.
        const __m512i even_pair = _mm512_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28, 1, 5, 9, 13, 17, 21, 25, 29);
        const __m512i odd_pair =
            _mm512_setr_epi32(2, 6, 10, 14, 18, 22, 26, 30, 3, 7, 11, 15, 19, 23, 27, 31);
        // Round 3: the first halves of the two eight-record sets, then the second halves.
        const __m512i first_halves =
            _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 16, 17, 18, 19, 20, 21, 22, 23);
        const __m512i second_halves =
            _mm512_setr_epi32(8, 9, 10, 11, 12, 13, 14, 15, 24, 25, 26, 27, 28, 29, 30, 31);
        for (int side = 0; side < 2; ++side) {  // fields 0-3, then 4-7
            const __m512* quads = side == 0 ? low : high;
            for (int m = 0; m < 2; ++m) {
                const __m512i pair = m == 0 ? even_pair : odd_pair;
                const __m512 first8 = _mm512_permutex2var_ps(quads[0], pair, quads[1]);
                const __m512 second8 = _mm512_permutex2var_ps(quads[2], pair, quads[3]);
                field[4 * side + 2 * m] = _mm512_permutex2var_ps(first8, first_halves, second8);
                field[4 * side + 2 * m + 1] = _mm512_permutex2var_ps(first8, second_halves, second8);
            }
        }
    }
    static Float broadcast_int(int x) { return _mm512_castsi512_ps(_mm512_set1_epi32(x)); }
    static Mask less_int(Float a, Float b) {
        return _mm512_cmplt_epi32_mask(_mm512_castps_si512(a), _mm512_castps_si512(b));
    }
    static Mask equal_int(Float a, Float b) {
        return _mm512_cmpeq_epi32_mask(_mm512_castps_si512(a), _mm512_castps_si512(b));
    }
    static Mask mask_from_bits(unsigned bits) { return static_cast<Mask>(bits); }
    // Through memory: GCC 12's 512-to-256-bit casts and extractions read an uninitialised source too.
    static float reduce_min(Float a) {
        alignas(64) float lanes[16];
        _mm512_store_ps(lanes, a);
        return Avx2::reduce_min(_mm256_min_ps(_mm256_load_ps(lanes), _mm256_load_ps(lanes + 8)));
    }
    static float reduce_max(Float a) {
        alignas(64) float lanes[16];
        _mm512_store_ps(lanes, a);
        return Avx2::reduce_max(_mm256_max_ps(_mm256_load_ps(lanes), _mm256_load_ps(lanes + 8)));
    }
    // The zero-masked forms with every lane set throughout, for the reason given at max() above.
    static void store_interleaved(float* p, Float a, Float b, Float c, Float d) {
        const __m512 ab_low = _mm512_maskz_unpacklo_ps(0xffff, a, b),
                     ab_high = _mm512_maskz_unpackhi_ps(0xffff, a, b);
        const __m512 cd_low = _mm512_maskz_unpacklo_ps(0xffff, c, d),
                     cd_high = _mm512_maskz_unpackhi_ps(0xffff, c, d);
        // Register r_k holds records k, k + 4, k + 8, k + 12 in its four 128-bit lanes.
        auto pairs = [](__m512 x, __m512 y, bool high) {
            const __m512d xd = _mm512_castps_pd(x), yd = _mm512_castps_pd(y);
            return _mm512_castpd_ps(high ? _mm512_maskz_unpackhi_pd(0xff, xd, yd)
                                         : _mm512_maskz_unpacklo_pd(0xff, xd, yd));
        };
        const __m512 r0 = pairs(ab_low, cd_low, false), r1 = pairs(ab_low, cd_low, true);
        const __m512 r2 = pairs(ab_high, cd_high, false), r3 = pairs(ab_high, cd_high, true);
        // 128-bit lanes: r01_low = r0.0 r0.1 r1.0 r1.1, and so on; then the 4 x 4 transpose of lanes.
        const __m512 r01_low = _mm512_maskz_shuffle_f32x4(0xffff, r0, r1, 0x44);
        const __m512 r23_low = _mm512_maskz_shuffle_f32x4(0xffff, r2, r3, 0x44);
        const __m512 r01_high = _mm512_maskz_shuffle_f32x4(0xffff, r0, r1, 0xee);
        const __m512 r23_high = _mm512_maskz_shuffle_f32x4(0xffff, r2, r3, 0xee);
        _mm512_storeu_ps(p, _mm512_maskz_shuffle_f32x4(0xffff, r01_low, r23_low, 0x88));
        _mm512_storeu_ps(p + 16, _mm512_maskz_shuffle_f32x4(0xffff, r01_low, r23_low, 0xdd));
        _mm512_storeu_ps(p + 32, _mm512_maskz_shuffle_f32x4(0xffff, r01_high, r23_high, 0x88));
        _mm512_storeu_ps(p + 48, _mm512_maskz_shuffle_f32x4(0xffff, r01_high, r23_high, 0xdd));
    }
    static Mask mask_and(Mask a, Mask b) { return static_cast<Mask>(a & b); }
    static Mask mask_or(Mask a, Mask b) { return static_cast<Mask>(a | b); }
    static unsigned bits(Mask a) { return a; }
    static unsigned sign_bits(Float a) { return _mm512_movepi32_mask(_mm512_castps_si512(a)); }
};
#endif

}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer::simd
