// Ray packets: up to 64 rays in structure-of-arrays layout, the fastest way into lancer for coherent rays
// (camera rays of an 8x8 pixel tile), as Embree's rtcIntersect16 is into Embree. A caller writes its rays
// straight into the packet's arrays (PinholeCamera::tile_rays does, in SIMD) and reads the answers from the
// hit packet's, so no ray is stored as a `Ray` record and moved again. Accel::intersect_packet takes them.
#pragma once

#include <cstddef>
#include <cstdint>

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

#include "lancer/ray.hpp"

namespace lancer {

// The rays of lanes [0, size). Lane order matters for speed only: every run of 16 lanes from a multiple of 16
// a 4x4 pixel block, and every run of 8 a 4x2 one, is what the packet kernels and Embree's packet calls are
// fastest on (PinholeCamera::tile_rays's order).
struct alignas(64) RayPacket {
    static constexpr int kMaxSize = 64;

    float origin[3][kMaxSize];
    float direction[3][kMaxSize];
    float tnear[kMaxSize];
    float tfar[kMaxSize];
    int size = 0;

    [[nodiscard]] Ray ray(int lane) const {
        return {{origin[0][lane], origin[1][lane], origin[2][lane]},
                {direction[0][lane], direction[1][lane], direction[2][lane]},
                tnear[lane],
                tfar[lane]};
    }
    void set(int lane, const Ray& ray) {
        for (int axis = 0; axis < 3; ++axis) {
            origin[axis][lane] = ray.origin[axis];
            direction[axis][lane] = ray.direction[axis];
        }
        tnear[lane] = ray.tnear, tfar[lane] = ray.tfar;
    }
};

// The closest hit of each lane of a RayPacket, field by field as in `Hit` (prim -1 on a miss).
struct alignas(64) HitPacket {
    float t[RayPacket::kMaxSize];
    std::int32_t prim[RayPacket::kMaxSize];
    float u[RayPacket::kMaxSize];
    float v[RayPacket::kMaxSize];

    [[nodiscard]] Hit hit(int lane) const { return {t[lane], prim[lane], u[lane], v[lane]}; }
    // The hits of lanes [first, first + 4) as four records (a row of a 4x4 pixel block): with SSE, one 4x4
    // transpose and a 16-byte store per record, where GCC writes a record built field by field in three.
    void copy_four(int first, Hit* out) const {
#if defined(__SSE2__)
        static_assert(sizeof(Hit) == 16 && offsetof(Hit, prim) == 4 && offsetof(Hit, u) == 8 &&
                      offsetof(Hit, v) == 12);
        __m128 t_row = _mm_loadu_ps(t + first),
               prim_row = _mm_loadu_ps(reinterpret_cast<const float*>(prim + first));
        __m128 u_row = _mm_loadu_ps(u + first), v_row = _mm_loadu_ps(v + first);
        _MM_TRANSPOSE4_PS(t_row, prim_row, u_row, v_row);
        auto* record = reinterpret_cast<float*>(out);
        _mm_storeu_ps(record, t_row);
        _mm_storeu_ps(record + 4, prim_row);
        _mm_storeu_ps(record + 8, u_row);
        _mm_storeu_ps(record + 12, v_row);
#else
        for (int k = 0; k < 4; ++k)
            out[k] = hit(first + k);
#endif
    }
    void set(int lane, const Hit& hit) {
        t[lane] = hit.t, prim[lane] = hit.prim, u[lane] = hit.u, v[lane] = hit.v;
    }
};

}  // namespace lancer
