// The watertight triangle test (Woop, Benthin & Wald 2013; Watertight in core/intersect.hpp) for 8 rays at
// once, AVX2, for the groups of plucker_packet: the rays of a group stand in the same leaf and test the same
// triangles. Every lane computes exactly the scalar test's operations in the scalar test's order (one IEEE
// rounding each, no fused multiply-add: -ffp-contract=off and separate mul/add intrinsics), so a lane's t, u
// and v are the scalar test's bits. Lanes must share the ray-space axes (kx, ky, kz), which coherent rays do;
// a lane with an edge function exactly 0, which the scalar test recomputes in double, is reported apart for
// the caller to test with the scalar code.
#pragma once

#if defined(__AVX2__)
#include <immintrin.h>

#include <array>
#include <cstdint>

#include "core/intersect.hpp"

namespace lancer::plucker {

// Up to 8 rays with the same (kx, ky, kz): their Watertight::RayData and intervals, one array per field.
struct WatertightLanes {
    static constexpr int kWidth = 8;
    int kx = 0, ky = 0, kz = 0;
    int count = 0;
    std::array<std::uint8_t, kWidth> lane{};                        // the packet lane of each SIMD lane
    alignas(32) std::array<std::array<float, kWidth>, 3> origin{};  // origin[kx], origin[ky], origin[kz]
    alignas(32) std::array<std::array<float, kWidth>, 3> shear{};   // shear_x, shear_y, shear_z
    alignas(32) std::array<float, kWidth> tnear{};
    alignas(32) std::array<float, kWidth> tfar{};

    // Appends a ray (with the axes of the first one appended) and its interval.
    void add(std::uint8_t packet_lane, const Watertight::RayData& data, float ray_tnear, float ray_tfar) {
        if (count == 0) kx = data.kx, ky = data.ky, kz = data.kz;
        const auto i = static_cast<std::size_t>(count++);
        lane[i] = packet_lane;
        origin[0][i] = data.origin[kx], origin[1][i] = data.origin[ky], origin[2][i] = data.origin[kz];
        shear[0][i] = data.shear_x, shear[1][i] = data.shear_y, shear[2][i] = data.shear_z;
        tnear[i] = ray_tnear, tfar[i] = ray_tfar;
    }

    struct Result {
        unsigned hits = 0;   // SIMD lanes with a hit in [tnear, tfar]: t, u, v below
        unsigned exact = 0;  // SIMD lanes with an edge function exactly 0: the scalar test decides
        alignas(32) std::array<float, kWidth> t{}, u{}, v{};
    };

    [[nodiscard]] Result intersect(const Triangle& tri) const {
        const __m256 ox = _mm256_load_ps(origin[0].data()), oy = _mm256_load_ps(origin[1].data()),
                     oz = _mm256_load_ps(origin[2].data());
        const __m256 sx = _mm256_load_ps(shear[0].data()), sy = _mm256_load_ps(shear[1].data()),
                     sz = _mm256_load_ps(shear[2].data());
        // a = v0 - o in the permuted axes, then the shear: ax = a[kx] - shear_x a[kz], ay likewise.
        const auto relative = [&](const Vec3f& vertex, __m256& x, __m256& y, __m256& z) {
            z = _mm256_sub_ps(_mm256_set1_ps(vertex[kz]), oz);
            x = _mm256_sub_ps(_mm256_sub_ps(_mm256_set1_ps(vertex[kx]), ox), _mm256_mul_ps(sx, z));
            y = _mm256_sub_ps(_mm256_sub_ps(_mm256_set1_ps(vertex[ky]), oy), _mm256_mul_ps(sy, z));
        };
        __m256 ax, ay, az, bx, by, bz, cx, cy, cz;
        relative(tri.v0, ax, ay, az);
        relative(tri.v1, bx, by, bz);
        relative(tri.v2, cx, cy, cz);
        const __m256 w0 = _mm256_sub_ps(_mm256_mul_ps(bx, cy), _mm256_mul_ps(by, cx));
        const __m256 w1 = _mm256_sub_ps(_mm256_mul_ps(cx, ay), _mm256_mul_ps(cy, ax));
        const __m256 w2 = _mm256_sub_ps(_mm256_mul_ps(ax, by), _mm256_mul_ps(ay, bx));
        const __m256 zero = _mm256_setzero_ps();
        const __m256 any_zero = _mm256_or_ps(
            _mm256_or_ps(_mm256_cmp_ps(w0, zero, _CMP_EQ_OQ), _mm256_cmp_ps(w1, zero, _CMP_EQ_OQ)),
            _mm256_cmp_ps(w2, zero, _CMP_EQ_OQ));
        const __m256 any_negative = _mm256_or_ps(
            _mm256_or_ps(_mm256_cmp_ps(w0, zero, _CMP_LT_OQ), _mm256_cmp_ps(w1, zero, _CMP_LT_OQ)),
            _mm256_cmp_ps(w2, zero, _CMP_LT_OQ));
        const __m256 any_positive = _mm256_or_ps(
            _mm256_or_ps(_mm256_cmp_ps(w0, zero, _CMP_GT_OQ), _mm256_cmp_ps(w1, zero, _CMP_GT_OQ)),
            _mm256_cmp_ps(w2, zero, _CMP_GT_OQ));
        const __m256 det = _mm256_add_ps(_mm256_add_ps(w0, w1), w2);
        // Not (mixed signs), and not det == 0 (unordered: a NaN det goes on, as in the scalar test).
        __m256 accept = _mm256_andnot_ps(_mm256_and_ps(any_negative, any_positive),
                                         _mm256_cmp_ps(det, zero, _CMP_NEQ_UQ));
        const __m256 scaled_az = _mm256_mul_ps(sz, az), scaled_bz = _mm256_mul_ps(sz, bz),
                     scaled_cz = _mm256_mul_ps(sz, cz);
        const __m256 inv_det = _mm256_div_ps(_mm256_set1_ps(1.0f), det);
        const __m256 t = _mm256_mul_ps(
            _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(w0, scaled_az), _mm256_mul_ps(w1, scaled_bz)),
                          _mm256_mul_ps(w2, scaled_cz)),
            inv_det);
        accept = _mm256_and_ps(accept, _mm256_cmp_ps(t, _mm256_load_ps(tnear.data()), _CMP_GE_OQ));
        accept = _mm256_and_ps(accept, _mm256_cmp_ps(t, _mm256_load_ps(tfar.data()), _CMP_LE_OQ));
        accept = _mm256_and_ps(accept, _mm256_cmp_ps(t, _mm256_set1_ps(kInfinity), _CMP_LT_OQ));
        Result result;
        const unsigned used = (1u << count) - 1u;
        result.exact = static_cast<unsigned>(_mm256_movemask_ps(any_zero)) & used;
        result.hits = static_cast<unsigned>(_mm256_movemask_ps(accept)) & used & ~result.exact;
        _mm256_store_ps(result.t.data(), t);
        _mm256_store_ps(result.u.data(), _mm256_mul_ps(w1, inv_det));
        _mm256_store_ps(result.v.data(), _mm256_mul_ps(w2, inv_det));
        return result;
    }
};

}  // namespace lancer::plucker
#endif
