// The rays of a packet that meet an instance, mapped into its object's frame together and culled by the
// object's box in lanes (AVX2): to_object's latency chain (the map's products, the distance to the object, a
// far origin's move) and the visit's box cull run once for four or eight rays instead of once a ray
// (docs/accel/instances.md, "A packet's rays mapped together"). Every mapped lane's object ray, and every
// cull, is the one-ray visit's bit for bit. The walk that uses them is in top_level_walk.hpp.
#pragma once

#if defined(__AVX2__)
#include <immintrin.h>

#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>

#include "accel/instance/affine.hpp"
#include "accel/instance/records.hpp"
#include "core/intersect.hpp"
#include "core/ray_conditioning.hpp"

namespace lancer::top_level {

// crosses for 8 rays at once, one per lane of 8-float rows (origin[axis], direction[axis], tnear, tfar,
// 32-byte aligned): bit k is ray k's answer. The same products, NaN rule and exit widening on the same
// floats; the largest entry and the smallest exit do not depend on the order in which they are taken
// (InstancedScene.ObjectBoxCullInLanesAnswersAsTheVisit, through cull_in_lanes).
[[nodiscard]] inline int crosses_lanes(const float* const (&origin)[3], const float* const (&direction)[3],
                                       const float* tnear, const float* tfar, const ObjectBox& box) {
    __m256 entry = _mm256_load_ps(tnear), exit = _mm256_load_ps(tfar);
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const __m256 from = _mm256_load_ps(origin[axis]);
        const __m256 inverse = _mm256_div_ps(_mm256_set1_ps(1.0f), _mm256_load_ps(direction[axis]));
        const __m256 to_lo = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(box.lo[axis]), from), inverse);
        const __m256 to_hi = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(box.hi[axis]), from), inverse);
        const __m256 unbounded = _mm256_cmp_ps(to_lo, to_hi, _CMP_UNORD_Q);
        const __m256 axis_exit = _mm256_max_ps(to_lo, to_hi);
        const __m256 widened = _mm256_mul_ps(
            axis_exit, _mm256_blendv_ps(_mm256_set1_ps(kSlabExitShrink), _mm256_set1_ps(kSlabExitGrow),
                                        _mm256_cmp_ps(axis_exit, _mm256_setzero_ps(), _CMP_GT_OQ)));
        entry = _mm256_max_ps(
            entry, _mm256_blendv_ps(_mm256_min_ps(to_lo, to_hi), _mm256_set1_ps(-kInfinity), unbounded));
        exit = _mm256_min_ps(exit, _mm256_blendv_ps(widened, _mm256_set1_ps(kInfinity), unbounded));
    }
    return _mm256_movemask_ps(_mm256_cmp_ps(entry, exit, _CMP_LE_OQ));
}

// The rays of a packet that meet one instance, a lane each in the order of the rays, mapped into its
// object's frame (map_together).
struct MappedRays {
    alignas(32) float origin[3][kPacketRays];
    alignas(32) float direction[3][kPacketRays];
    alignas(32) float tnear[kPacketRays];  // the interval in the object's frame
    alignas(32) float tfar[kPacketRays];
    alignas(32) double shift[kPacketRays];      // a far lane's (ObjectRay::shift)
    alignas(32) float world_tfar[kPacketRays];  // the world ray's tfar, clipped by its closest hit so far
    std::uint8_t ray[kPacketRays];              // the lane's ray in the packet
    RayMask mapped = 0;                         // the lanes whose object ray is to_object's
    RayMask far = 0;                            // of those, the ones whose origin was moved (far)
    RayMask culled = 0;                         // of those, the ones whose visit ends at the object box cull
    RayMask crossing = 0;                       // and the ones that pass it as they are

    // Lane `lane`'s object ray (a mapped one).
    [[nodiscard]] ObjectRay object_ray(int lane) const {
        const auto l = static_cast<std::size_t>(lane);
        return {{{origin[0][l], origin[1][l], origin[2][l]},
                 {direction[0][l], direction[1][l], direction[2][l]},
                 tnear[l],
                 tfar[l]},
                (far >> lane) & 1 ? shift[l] : 0.0};
    }
};

// The visit's object box cull on the mapped lanes, 8 to a register, for an object at its own scale: the
// lanes that is_ordinary lets through as they are (its comparisons on the same floats) and that miss the
// box (crosses_lanes) go to `culled`, those that cross it to `crossing`
// (InstancedScene.ObjectBoxCullInLanesAnswersAsTheVisit).
inline void cull_in_lanes(const InstanceRecord& record, int count, MappedRays& mapped) {
    const __m256 sign_bit = _mm256_set1_ps(-0.0f);
    for (int first = 0; first < count; first += 8) {
        const auto at = static_cast<std::size_t>(first);
        const float* const origin[3] = {&mapped.origin[0][at], &mapped.origin[1][at], &mapped.origin[2][at]};
        const float* const direction[3] = {&mapped.direction[0][at], &mapped.direction[1][at],
                                           &mapped.direction[2][at]};
        __m256 largest_direction = _mm256_setzero_ps(), largest_offset = _mm256_setzero_ps();
        for (std::size_t axis = 0; axis < 3; ++axis) {
            const __m256 offset = _mm256_sub_ps(_mm256_load_ps(origin[axis]),
                                                _mm256_set1_ps(record.object_centre[static_cast<int>(axis)]));
            largest_direction =
                _mm256_max_ps(largest_direction, _mm256_andnot_ps(sign_bit, _mm256_load_ps(direction[axis])));
            largest_offset = _mm256_max_ps(largest_offset, _mm256_andnot_ps(sign_bit, offset));
        }
        const __m256 as_is = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps(largest_direction, _mm256_set1_ps(kDirectionLowest), _CMP_GE_OQ),
                          _mm256_cmp_ps(largest_direction, _mm256_set1_ps(kDirectionHighest), _CMP_LE_OQ)),
            _mm256_cmp_ps(largest_offset, _mm256_set1_ps(record.far_limit), _CMP_LE_OQ));
        const int crossing =
            crosses_lanes(origin, direction, &mapped.tnear[at], &mapped.tfar[at], record.object_box);
        const int ordinary = _mm256_movemask_ps(as_is);
        mapped.culled |= static_cast<RayMask>(ordinary & ~crossing) << first;
        mapped.crossing |= static_cast<RayMask>(ordinary & crossing) << first;
    }
    mapped.culled &= mapped.mapped, mapped.crossing &= mapped.mapped;
}

// The `met` rays of `rays` mapped into `record`'s object frame four to a register of doubles, each with its
// world interval [tnear, world_tfar(i)], then culled by the object's box (cull_in_lanes). The lanes run
// InverseAffine's own steps, so a mapped lane's object ray is to_object's bit for bit; a lane with a NaN
// along the way, where to_object's far test depends on where the NaN is, is left unmapped, for the one-ray
// visit. Returns the number of lanes.
template <class WorldTfar>
int map_together(const InstanceRecord& record, std::span<const Ray> rays, RayMask met, WorldTfar&& world_tfar,
                 MappedRays& mapped) {
    constexpr int kLanes = 4;
    // origin x, y, z, then direction x, y, z; rows of a whole number of 16-byte groups.
    alignas(16) float gathered[6][kPacketRays + kLanes];
    int count = 0;
    for (RayMask each = met; each != 0; each &= each - 1, ++count) {
        const int i = std::countr_zero(each);
        const Ray& ray = rays[static_cast<std::size_t>(i)];
        const auto lane = static_cast<std::size_t>(count);
        mapped.ray[lane] = static_cast<std::uint8_t>(i);
        for (int axis = 0; axis < 3; ++axis) {
            gathered[axis][lane] = ray.origin[axis];
            gathered[3 + axis][lane] = ray.direction[axis];
        }
        mapped.tnear[lane] = ray.tnear;
        mapped.tfar[lane] = mapped.world_tfar[lane] = world_tfar(i);
    }
    for (int lane = count; lane % kLanes != 0; ++lane) {  // a whole last register: copies of the first ray
        for (auto& row : gathered)
            row[lane] = row[0];
        const auto l = static_cast<std::size_t>(lane);
        mapped.tnear[l] = mapped.tnear[0], mapped.tfar[l] = mapped.world_tfar[l] = mapped.world_tfar[0];
    }
    const DoubleLanes centre[3] = {DoubleLanes(double(record.object_centre.x)),
                                   DoubleLanes(double(record.object_centre.y)),
                                   DoubleLanes(double(record.object_centre.z))};
    const __m256d far_limit = _mm256_set1_pd(double(record.far_limit));
    const __m256d sign_bit = _mm256_set1_pd(-0.0);
    mapped.mapped = mapped.far = mapped.culled = mapped.crossing = 0;
    for (int first = 0; first < count; first += kLanes) {
        const auto at = static_cast<std::size_t>(first);
        const auto lanes_of = [&](int row) {
            return DoubleLanes(_mm256_cvtps_pd(_mm_load_ps(&gathered[row][at])));
        };
        const DoubleLanes origin[3] = {lanes_of(0), lanes_of(1), lanes_of(2)};
        const DoubleLanes direction[3] = {lanes_of(3), lanes_of(4), lanes_of(5)};
        DoubleLanes local_origin[3] = {origin[0], origin[1], origin[2]};
        DoubleLanes local_direction[3] = {direction[0], direction[1], direction[2]};
        record.to_object.map(origin, direction, local_origin, local_direction);
        // to_object's far test, |p' - centre| > far_limit on some axis, and the lanes with a NaN.
        __m256d far = _mm256_setzero_pd(), unordered = _mm256_setzero_pd();
        for (int axis = 0; axis < 3; ++axis) {
            const __m256d offset = _mm256_andnot_pd(sign_bit, (local_origin[axis] - centre[axis]).lanes);
            far = _mm256_or_pd(far, _mm256_cmp_pd(offset, far_limit, _CMP_GT_OQ));
            unordered =
                _mm256_or_pd(unordered, _mm256_cmp_pd(offset, local_direction[axis].lanes, _CMP_UNORD_Q));
        }
        const int far_lanes = _mm256_movemask_pd(far);
        if (far_lanes != 0) {
            DoubleLanes moved[3] = {local_origin[0], local_origin[1], local_origin[2]};
            const DoubleLanes shift = InverseAffine::move_towards(centre, moved, local_direction);
            _mm256_store_pd(&mapped.shift[at], shift.lanes);
            // A far lane's interval moves with its origin; a near lane's is the world's.
            const __m128 world_tnear = _mm_load_ps(&mapped.tnear[at]);
            __m128 moved_tnear, moved_tfar;
            InverseAffine::move_interval(world_tnear, _mm_load_ps(&mapped.world_tfar[at]), shift, moved_tnear,
                                         moved_tfar);
            const __m128 far_floats = narrow_mask(far);
            _mm_store_ps(&mapped.tnear[at], _mm_blendv_ps(world_tnear, moved_tnear, far_floats));
            _mm_store_ps(&mapped.tfar[at],
                         _mm_blendv_ps(_mm_load_ps(&mapped.tfar[at]), moved_tfar, far_floats));
            for (int axis = 0; axis < 3; ++axis) {
                local_origin[axis] =
                    DoubleLanes(_mm256_blendv_pd(local_origin[axis].lanes, moved[axis].lanes, far));
                unordered = _mm256_or_pd(unordered, _mm256_cmp_pd(local_origin[axis].lanes,
                                                                  local_origin[axis].lanes, _CMP_UNORD_Q));
            }
        }
        for (int axis = 0; axis < 3; ++axis) {
            _mm_store_ps(&mapped.origin[axis][at], _mm256_cvtpd_ps(local_origin[axis].lanes));
            _mm_store_ps(&mapped.direction[axis][at], _mm256_cvtpd_ps(local_direction[axis].lanes));
        }
        const int ordered_lanes = ~_mm256_movemask_pd(unordered) & 0xf;
        mapped.mapped |= static_cast<RayMask>(ordered_lanes) << first;
        mapped.far |= static_cast<RayMask>(far_lanes & ordered_lanes) << first;
    }
    if (count < static_cast<int>(kPacketRays)) mapped.mapped &= (RayMask{1} << count) - 1;
    mapped.far &= mapped.mapped;
    if (record.traced->scale_exponent() == 0) cull_in_lanes(record, count, mapped);
    return count;
}

}  // namespace lancer::top_level
#endif
