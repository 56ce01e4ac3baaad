// The two-level scene's records and its walk (InstancedScene, lancer/instances.hpp): what the walk reads of
// objects and instances, and the top level walked front to back with each instance's object traced in its
// frame. The scene's building, refit and interface are in instanced_scene.cpp. docs/accel/instances.md has
// the design note.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#if defined(__SSE4_1__) || defined(__AVX2__)
#include <immintrin.h>
#endif
#include <memory>
#include <span>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/interval_cull.hpp"
#include "accel/instance/affine.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/accel.hpp"
#include "lancer/instances.hpp"

namespace lancer::top_level {

struct ObjectRecord {
    std::shared_ptr<const Accel> structure;
    // What the walk traces: the structure, or the single-ray structure a packet structure holds.
    const Accel* traced = nullptr;
    SingleRayWalk walk;  // traced's one-ray walk, where it has one
    // The triangles the scene flattened, when it built the object itself.
    std::shared_ptr<const std::vector<Triangle>> triangles;
    std::size_t primitives = 0;
};

// An object's box as the cull before an instance visit (crosses) reads it: the three axes in SSE lanes, the
// fourth 0.
struct alignas(16) ObjectBox {
    float lo[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    float hi[4] = {0.0f, 0.0f, 0.0f, 0.0f};

    ObjectBox() = default;
    explicit ObjectBox(const Box3f& box)
        : lo{box.lo.x, box.lo.y, box.lo.z, 0.0f}, hi{box.hi.x, box.hi.y, box.hi.z, 0.0f} {}
    [[nodiscard]] Box3f box() const { return {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}}; }
};

// Whether `ray` crosses `box` within [tnear, tfar]: intersect_box's slab test (core/intersect.hpp), its
// products, NaN rule (a NaN plane leaves the slab unbounded) and exit widening, on the three axes at once;
// the same answer, since the largest entry and the smallest exit do not depend on the order in which they
// are taken (InstancedScene.ObjectBoxCullAnswersAsTheSlabTest).
[[nodiscard]] inline bool crosses(const Ray& ray, const ObjectBox& box) {
#if defined(__SSE4_1__)
    const __m128 origin = _mm_loadu_ps(&ray.origin.x);        // x, y, z and direction.x
    const __m128 direction = _mm_loadu_ps(&ray.direction.x);  // x, y, z and tnear
    const __m128 inverse = _mm_div_ps(_mm_set1_ps(1.0f), direction);
    const __m128 to_lo = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(box.lo), origin), inverse);
    const __m128 to_hi = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(box.hi), origin), inverse);
    // The fourth lane, and an axis with a NaN plane, unbounded.
    const __m128 unbounded =
        _mm_or_ps(_mm_cmpunord_ps(to_lo, to_hi), _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, -1)));
    const __m128 exit = _mm_max_ps(to_lo, to_hi);
    const __m128 widened =
        _mm_mul_ps(exit, _mm_blendv_ps(_mm_set1_ps(kSlabExitShrink), _mm_set1_ps(kSlabExitGrow),
                                       _mm_cmpgt_ps(exit, _mm_setzero_ps())));
    __m128 t0 = _mm_blendv_ps(_mm_min_ps(to_lo, to_hi), _mm_set1_ps(-kInfinity), unbounded);
    __m128 t1 = _mm_blendv_ps(widened, _mm_set1_ps(kInfinity), unbounded);
    t0 = _mm_max_ps(t0, _mm_movehl_ps(t0, t0));
    t1 = _mm_min_ps(t1, _mm_movehl_ps(t1, t1));
    t0 = _mm_max_ss(_mm_max_ss(t0, _mm_shuffle_ps(t0, t0, 1)), _mm_set_ss(ray.tnear));
    t1 = _mm_min_ss(_mm_min_ss(t1, _mm_shuffle_ps(t1, t1, 1)), _mm_set_ss(ray.tfar));
    return _mm_comile_ss(t0, t1) != 0;
#else
    float t_entry = 0.0f, t_exit = 0.0f;
    return intersect_box(SlabRay(ray), box.box(), ray.tnear, ray.tfar, t_entry, t_exit);
#endif
}

#if defined(__AVX2__)
// crosses for 8 rays at once, one per lane of 8-float rows (origin[axis], direction[axis], tnear, tfar,
// 32-byte aligned): bit k is ray k's answer. The same products, NaN rule and exit widening on the same
// floats; the largest entry and the smallest exit do not depend on the order in which they are taken
// (InstancedScene.ObjectBoxCullInLanesAnswersAsCrosses).
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
#endif

// is_valid (lancer/ray.hpp) on the ray's 8 floats at once: origin, direction and tnear finite, a nonzero
// direction component, tfar not NaN and tnear <= tfar. The same answer (checked by
// InstancedScene.RayValidityAnswersAsIsValid) in a few vector instructions instead of is_valid's scalar tests
// of each component (docs/accel/instances.md, "The visit's overhead, cut").
[[nodiscard]] inline bool is_valid_ray(const Ray& ray) {
#if defined(__AVX2__)
    static_assert(sizeof(Ray) == 8 * sizeof(float));
    const __m256 lanes = _mm256_loadu_ps(&ray.origin.x);  // origin, direction, tnear, tfar
    const __m256 magnitude = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), lanes);
    const int finite = _mm256_movemask_ps(
        _mm256_cmp_ps(magnitude, _mm256_set1_ps(std::numeric_limits<float>::max()), _CMP_LE_OQ));
    const int nonzero = _mm256_movemask_ps(_mm256_cmp_ps(lanes, _mm256_setzero_ps(), _CMP_NEQ_UQ));
    return (finite & 0x7f) == 0x7f && (nonzero & 0x38) != 0 && ray.tfar == ray.tfar && ray.tnear <= ray.tfar;
#else
    return is_valid(ray);
#endif
}

// What the walk reads of an instance: 192 bytes.
struct InstanceRecord {
    InverseAffine to_object;
    const Accel* traced = nullptr;
    std::uint32_t object = 0;
    // Ray conditioning's far-origin frame of the object's box (FarOriginFrame): its centre, and the distance
    // beyond which an origin is far.
    Vec3f object_centre;
    float far_limit = kInfinity;
    SingleRayWalk walk;  // the object's (ObjectRecord::walk)
    // The object's box grown by its geometric tolerance: the box the top level maps to the world.
    ObjectBox object_box;
};
static_assert(sizeof(InstanceRecord) == 192);

// The top level's nodes: the wide BVH's (accel/bvh/bvh_wide.hpp), 8 children tested at once.
constexpr int kTopWidth = 8;
using TopNode = WideBvhNode<kTopWidth>;

}  // namespace lancer::top_level

namespace lancer {

// The walk of a committed top level over `nodes` and `records` (InstancedScene::State's). A member of
// InstancedScene, for Accel's batch calls on the objects (its friend's).
class InstancedScene::Walk {
    using TopNode = top_level::TopNode;
    using InstanceRecord = top_level::InstanceRecord;
    static constexpr int kTopWidth = top_level::kTopWidth;

  public:
    // `bounds`: the scene's box. `coherent_width`: the widest box of origins (or, for occlusion rays, of
    // ends) from which a packet of rays walks the top level together (walk_packet).
    Walk(const std::vector<TopNode>& nodes, const std::vector<InstanceRecord>& records, const Box3f& bounds,
         float coherent_width)
        : nodes_(nodes),
          records_(records),
          coherent_width_(coherent_width),
          scene_magnitude_(std::max(max_component(abs(bounds.lo)), max_component(abs(bounds.hi)))) {}

    // Each conditioned ray walked once: answers[i] the closest hit (InstanceHit) or whether the ray is
    // occluded (std::uint8_t, kAnyHit). Invalid rays miss. Consecutive rays that start together (a camera
    // tile), or occlusion rays that end together (shadow rays towards one light), walk the top level as a
    // packet; any other ray walks alone. Either way a ray gets its own walk's answer.
    template <bool kAnyHit, class Answer>
    void each(std::span<const Ray> traced, std::span<Answer> answers, TraversalCounters* counters) const {
        const auto trace = [&]<bool kCount>() {
            TraversalCounters counts;
#if defined(__AVX2__)
            Packet packet;
#endif
            for (std::size_t first = 0; first < traced.size(); first += kPacketRays) {
                const std::size_t count = std::min<std::size_t>(kPacketRays, traced.size() - first);
#if defined(__AVX2__)
                const std::span<const Ray> rays = traced.subspan(first, count);
                if (count >= kFewestPacketRays && load<kAnyHit>(rays, packet)) {
                    walk_packet<kAnyHit, kCount>(rays, packet, answers.subspan(first, count), counts);
                    continue;
                }
#endif
                for (std::size_t i = first; i < first + count; ++i) {
                    InstanceHit best;
                    const bool found =
                        top_level::is_valid_ray(traced[i]) && walk<kAnyHit, kCount>(traced[i], best, counts);
                    if constexpr (kAnyHit) {
                        answers[i] = found;
                    } else {
                        answers[i] = best;
                    }
                }
            }
            if constexpr (kCount) {
                counts.rays = traced.size();
                *counters += counts;
            }
        };
        counters != nullptr ? trace.template operator()<true>() : trace.template operator()<false>();
    }

  private:
    static constexpr std::size_t kPacketRays = 64;
    // Fewer rays than this walk alone: the packet's loading and culls pay for several rays.
    static constexpr std::size_t kFewestPacketRays = 8;
    using RayMask = std::uint64_t;

#if defined(__AVX2__)
    // A packet's rays, one array per coordinate so that a group of 8 loads in one instruction, and their
    // bounds as intervals for the cull. Lanes past the packet's rays, and invalid rays, have tnear = +inf
    // and tlimit = -inf, which no box test passes.
    struct Packet {
        alignas(32) float origin[3][kPacketRays];
        alignas(32) float inv_direction[3][kPacketRays];
        alignas(32) float tnear[kPacketRays];
        alignas(32) float tlimit[kPacketRays];  // tfar, or the closest hit so far: the walk's box test limit
        std::array<int, 3> near_side;           // the face each ray enters a box by (TopNode::kLo or kHi)
        // The cull's rays: the packet's own, or (from_ends) the packet seen from its rays' ends, which the
        // cull takes up to ends_limit.
        PacketInterval interval;
        bool from_ends = false;
        float ends_limit = 0.0f;
        RayMask valid = 0;
    };

    // Loads `rays` into `packet`; false when they cannot walk together: two valid rays disagree on a
    // direction sign, a reciprocal direction is not finite (whose NaN plane distances the cull does not
    // bound), or the valid rays' origins spread wider than coherent_width_. Occlusion rays whose origins
    // spread but whose ends o + tfar d lie that close together (shadow rays aimed at one point light) walk
    // together too, culled from their ends (ends_interval). A ray that breaks the rules ends the loading at
    // once: incoherent batches (diffuse bounces) pay a few rays' tests.
    template <bool kAnyHit>
    [[nodiscard]] bool load(std::span<const Ray> rays, Packet& packet) const {
        Box3f origins, ends, reciprocals;
        Vec3f reach;  // the largest |tfar d| on each axis
        float tnear_min = kInfinity, length = 0.0f;
        bool forward_and_finite = true;  // every valid ray has tnear >= 0 and a finite end
        int signs = -1;                  // bit a: the valid rays' direction is negative on axis a
        packet.valid = 0;
        for (std::size_t i = 0; i < kPacketRays; ++i) {
            if (i >= rays.size() || !top_level::is_valid_ray(rays[i])) {
                for (std::size_t axis = 0; axis < 3; ++axis)
                    packet.origin[axis][i] = 0.0f, packet.inv_direction[axis][i] = 1.0f;
                packet.tnear[i] = kInfinity, packet.tlimit[i] = -kInfinity;
                continue;
            }
            const Ray& ray = rays[i];
            const int ray_signs = (std::signbit(ray.direction.x) ? 1 : 0) |
                                  (std::signbit(ray.direction.y) ? 2 : 0) |
                                  (std::signbit(ray.direction.z) ? 4 : 0);
            if (signs < 0) signs = ray_signs;
            if (ray_signs != signs) return false;
            const SlabRay slab(ray);
            if (!(max_component(abs(slab.inv_direction)) < kInfinity)) return false;
            for (std::size_t axis = 0; axis < 3; ++axis) {
                packet.origin[axis][i] = slab.origin[static_cast<int>(axis)];
                packet.inv_direction[axis][i] = slab.inv_direction[static_cast<int>(axis)];
            }
            origins.extend(slab.origin), reciprocals.extend(slab.inv_direction);
            if constexpr (kAnyHit) {
                const Vec3f along = ray.direction * ray.tfar;
                const Vec3f end = ray.origin + along;
                forward_and_finite =
                    forward_and_finite && ray.tnear >= 0.0f && max_component(abs(end)) < kInfinity;
                ends.extend(end), reach = max(reach, abs(along));
                length = std::max(length, ray.tfar - ray.tnear);
            }
            const bool ends_together =
                kAnyHit && forward_and_finite && max_component(ends.extent()) <= coherent_width_;
            if (max_component(origins.extent()) > coherent_width_ && !ends_together) return false;
            packet.tnear[i] = ray.tnear, packet.tlimit[i] = ray.tfar;
            tnear_min = std::min(tnear_min, ray.tnear);
            packet.valid |= RayMask{1} << i;
        }
        if (packet.valid == 0) return false;
        for (std::size_t axis = 0; axis < 3; ++axis)
            packet.near_side[axis] = (signs >> axis) & 1 ? TopNode::kHi : TopNode::kLo;
        packet.from_ends = max_component(origins.extent()) > coherent_width_;
        if (packet.from_ends) {
            ends_interval(packet, ends, reciprocals, reach, length);
            return true;
        }
        packet.interval.near_side = packet.near_side;
        for (std::size_t axis = 0; axis < 3; ++axis) {
            const auto a = static_cast<int>(axis);
            packet.interval.set_axis(axis, origins.lo[a], origins.hi[a], reciprocals.lo[a],
                                     reciprocals.hi[a]);
        }
        packet.interval.tnear_min = tnear_min;
        return true;
    }

    // The cull of occlusion rays that end together, from their ends: reversed, each ray starts at its end
    // o + tfar d and goes along -d, and its interval [tnear, tfar] becomes [0, tfar - tnear], so the packet
    // is a camera packet at the ends (a point light). The interval holds origins in the box of the ends and
    // reciprocals -1/d, over [0, the longest tfar - tnear]. The box is grown by 2^-16 of the magnitudes the
    // roundings scale with (the ends, the reach |tfar d| and the scene's coordinates): far above the ends'
    // rounding, the distance by which a ray's own forward slab test may pass a box that its exact segment
    // misses, and the reversed test's rounding, a few 2^-24 of them each. A box some ray's own test passes
    // is therefore never culled. Each ray's box tests and visits stay forward (box_groups, visit).
    void ends_interval(Packet& packet, const Box3f& ends, const Box3f& reciprocals, const Vec3f& reach,
                       float length) const {
        constexpr float kMargin = 0x1p-16f;
        for (std::size_t axis = 0; axis < 3; ++axis) {
            const auto a = static_cast<int>(axis);
            const float magnitude =
                reach[a] + std::max(std::fabs(ends.lo[a]), std::fabs(ends.hi[a])) + scene_magnitude_;
            const float margin = kMargin * magnitude;
            packet.interval.near_side[axis] = 1 - packet.near_side[axis];
            packet.interval.set_axis(axis, ends.lo[a] - margin, ends.hi[a] + margin, -reciprocals.hi[a],
                                     -reciprocals.lo[a]);
        }
        packet.interval.tnear_min = 0.0f;
        packet.ends_limit = length * (1.0f + kMargin);
    }

    // The rays of a packet that meet an instance child, in lanes, mapped into its object's frame together
    // (map_together).
    struct MappedRays {
        alignas(32) float origin[3][kPacketRays];
        alignas(32) float direction[3][kPacketRays];
        alignas(32) float tnear[kPacketRays];  // the interval in the object's frame
        alignas(32) float tfar[kPacketRays];
        alignas(32) double shift[kPacketRays];  // a far lane's (ObjectRay::shift)
        float world_tfar[kPacketRays];          // the ray's tfar, clipped by its closest hit so far (clipped)
        std::uint8_t ray[kPacketRays];          // the lane's ray in the packet
        RayMask mapped = 0;                     // the lanes whose object ray is to_object's
        RayMask far = 0;                        // of those, the ones whose origin was moved (far)
        RayMask culled = 0;                     // of those, the ones whose visit ends at the object box cull
        RayMask crossing = 0;                   // and the ones that pass it as they are

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

    // The `met` rays mapped into instance `id`'s frame four to a register of doubles: to_object's latency
    // chain (the map's products, the distance to the object, a far origin's move) run once for four rays
    // instead of once a ray (docs/accel/instances.md, "A packet's rays mapped together"). The lanes run
    // InverseAffine's own steps, so a mapped lane's object ray is to_object's bit for bit; a lane with a NaN
    // along the way, where to_object's far test depends on where the NaN is, is left unmapped, to visit.
    // Returns the number of lanes, in the order of the rays.
    template <bool kAnyHit>
    int map_together(std::uint32_t id, std::span<const Ray> rays, RayMask met,
                     const std::array<InstanceHit, kPacketRays>& best, MappedRays& mapped) const {
        constexpr int kLanes = 4;
        const InstanceRecord& record = records_[id];
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
            mapped.world_tfar[lane] = kAnyHit ? ray.tfar : clipped(ray, best[static_cast<std::size_t>(i)]);
        }
        for (int lane = count; lane % kLanes != 0; ++lane)  // a whole last register: copies of the first ray
            for (auto& row : gathered)
                row[lane] = row[0];
        const DoubleLanes centre[3] = {DoubleLanes(double(record.object_centre.x)),
                                       DoubleLanes(double(record.object_centre.y)),
                                       DoubleLanes(double(record.object_centre.z))};
        const __m256d far_limit = _mm256_set1_pd(double(record.far_limit));
        const __m256d sign_bit = _mm256_set1_pd(-0.0);
        mapped.mapped = 0, mapped.far = 0;
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
                for (int axis = 0; axis < 3; ++axis) {
                    local_origin[axis] =
                        DoubleLanes(_mm256_blendv_pd(local_origin[axis].lanes, moved[axis].lanes, far));
                    unordered = _mm256_or_pd(
                        unordered,
                        _mm256_cmp_pd(local_origin[axis].lanes, local_origin[axis].lanes, _CMP_UNORD_Q));
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
        for (int lane = 0; lane < count; ++lane) {
            const auto l = static_cast<std::size_t>(lane);
            Ray world = rays[mapped.ray[l]], local;
            world.tfar = mapped.world_tfar[l];
            local.tnear = world.tnear, local.tfar = world.tfar;
            if ((mapped.far >> lane) & 1) InverseAffine::move_interval(world, mapped.shift[l], local);
            mapped.tnear[l] = local.tnear, mapped.tfar[l] = local.tfar;
        }
        mapped.culled = mapped.crossing = 0;
        if (record.traced->scale_exponent() == 0) cull_in_lanes(record, count, mapped);
        return count;
    }

    // visit_mapped's object box cull on the mapped lanes, 8 to a register, for an object at its own scale:
    // the lanes is_ordinary lets through as they are (its comparisons on the same floats) that miss the box
    // (crosses_lanes) go to `culled`, those that cross it to `crossing`.
    static void cull_in_lanes(const InstanceRecord& record, int count, MappedRays& mapped) {
        const __m256 sign_bit = _mm256_set1_ps(-0.0f);
        for (int first = 0; first < count; first += 8) {
            const auto at = static_cast<std::size_t>(first);
            const float* const origin[3] = {&mapped.origin[0][at], &mapped.origin[1][at],
                                            &mapped.origin[2][at]};
            const float* const direction[3] = {&mapped.direction[0][at], &mapped.direction[1][at],
                                               &mapped.direction[2][at]};
            __m256 largest_direction = _mm256_setzero_ps(), largest_offset = _mm256_setzero_ps();
            for (std::size_t axis = 0; axis < 3; ++axis) {
                const __m256 offset =
                    _mm256_sub_ps(_mm256_load_ps(origin[axis]),
                                  _mm256_set1_ps(record.object_centre[static_cast<int>(axis)]));
                largest_direction = _mm256_max_ps(
                    largest_direction, _mm256_andnot_ps(sign_bit, _mm256_load_ps(direction[axis])));
                largest_offset = _mm256_max_ps(largest_offset, _mm256_andnot_ps(sign_bit, offset));
            }
            const __m256 as_is = _mm256_and_ps(
                _mm256_and_ps(
                    _mm256_cmp_ps(largest_direction, _mm256_set1_ps(kDirectionLowest), _CMP_GE_OQ),
                    _mm256_cmp_ps(largest_direction, _mm256_set1_ps(kDirectionHighest), _CMP_LE_OQ)),
                _mm256_cmp_ps(largest_offset, _mm256_set1_ps(record.far_limit), _CMP_LE_OQ));
            const int crossing = top_level::crosses_lanes(origin, direction, &mapped.tnear[at],
                                                          &mapped.tfar[at], record.object_box);
            const int ordinary = _mm256_movemask_ps(as_is);
            mapped.culled |= static_cast<RayMask>(ordinary & ~crossing) << first;
            mapped.crossing |= static_cast<RayMask>(ordinary & crossing) << first;
        }
        mapped.culled &= mapped.mapped, mapped.crossing &= mapped.mapped;
    }

    // The largest box test limit of the `alive` rays: where the cull stops.
    [[nodiscard]] static float largest_limit(const Packet& packet, RayMask alive) {
        float largest = -kInfinity;
        for (RayMask rest = alive; rest != 0; rest &= rest - 1)
            largest = std::max(largest, packet.tlimit[std::countr_zero(rest)]);
        return largest;
    }

    // The top level walked once for the packet's rays (Overbeck et al.'s interval cull, as bvh8_packet's
    // camera packets walk bvh8: interval_cull.hpp): the children that some ray may meet are pushed,
    // farthest first; a popped child is kept for the rays whose own box test meets it within their closest
    // hit so far, and each of those rays visits an instance child as walk_from does. A ray therefore visits
    // every instance its own walk would visit before its final hit, and its answer, which does not depend
    // on the order of its visits (docs/numerical-contract.md, "Instances"), is its own walk's.
    template <bool kAnyHit, bool kCount, class Answer>
    void walk_packet(std::span<const Ray> rays, Packet& packet, std::span<Answer> answers,
                     TraversalCounters& counts) const {
        struct StackEntry {
            const TopNode* parent;
            int slot;
            float entry;
            RayMask rays;
        };
        std::array<InstanceHit, kPacketRays> best{};
        if constexpr (kAnyHit) std::fill(answers.begin(), answers.end(), Answer{});
        RayMask alive = packet.valid;
        TraversalCounters object_counts;
        TraversalCounters* object_counters = kCount ? &object_counts : nullptr;
        std::array<StackEntry, kTopWidth * BvhAccel::kMaxDepth + 1> stack;
        int stack_size = 0;
        MappedRays mapped;
        float limit_max = packet.from_ends ? packet.ends_limit : largest_limit(packet, alive);
        const TopNode* node = nodes_.empty() ? nullptr : &nodes_[0];
        RayMask node_rays = alive;
        while (node != nullptr) {
            if constexpr (kCount)
                counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(node_rays));
            alignas(32) float entry[kTopWidth];
            std::array<int, kTopWidth> order;
            const int count = order_by_entry<kTopWidth>(
                cull_children(*node, packet.interval, limit_max, entry), entry, order);
            for (int k = count - 1; k >= 0; --k) {
                const int slot = order[static_cast<std::size_t>(k)];
                stack[static_cast<std::size_t>(stack_size++)] = {node, slot, entry[slot], node_rays};
            }
            node = nullptr;
            while (node == nullptr && stack_size > 0) {
                const StackEntry popped = stack[static_cast<std::size_t>(--stack_size)];
                if (popped.entry > limit_max) continue;
                // Each ray's own test, walk_from's (its kForward form decides alike for tnear >= 0).
                const RayMask met = box_groups<simd::Avx2>(packet, packet.near_side, *popped.parent,
                                                           popped.slot, popped.rays & alive);
                if (met == 0) continue;
                const std::uint32_t child = popped.parent->child[popped.slot];
                if (popped.parent->prim_count[popped.slot] == 0) {
                    node = &nodes_[child], node_rays = met;
                    break;
                }
                const int mapped_count = map_together<kAnyHit>(child, rays, met, best, mapped);
                for (int lane = 0; lane < mapped_count; ++lane) {
                    const int i = mapped.ray[lane];
                    if constexpr (kCount) ++counts.nodes_visited;
                    // A culled visit finds nothing: the ray's answer and box test limit stay as they are.
                    if ((mapped.culled >> lane) & 1) continue;
                    const Ray& ray = rays[static_cast<std::size_t>(i)];
                    InstanceHit& hit = best[static_cast<std::size_t>(i)];
                    bool found = false;
                    if ((mapped.mapped >> lane) & 1) {
                        Ray world = ray;
                        world.tfar = mapped.world_tfar[lane];
                        const ObjectRay local = mapped.object_ray(lane);
                        found = (mapped.crossing >> lane) & 1
                                    ? visit_mapped<kAnyHit, true>(child, records_[child], world, local, hit,
                                                                  object_counters)
                                    : visit_mapped<kAnyHit>(child, records_[child], world, local, hit,
                                                            object_counters);
                    } else {
                        found = visit<kAnyHit>(child, ray, hit, object_counters);
                    }
                    if constexpr (kAnyHit) {
                        if (found) {
                            answers[static_cast<std::size_t>(i)] = 1;
                            alive &= ~(RayMask{1} << i);
                        }
                    } else {
                        packet.tlimit[i] = hit.hit() ? hit.t : ray.tfar;
                    }
                }
                if constexpr (kAnyHit) {
                    if (alive == 0) break;
                } else {
                    limit_max = largest_limit(packet, alive);
                }
            }
        }
        if constexpr (!kAnyHit) std::copy_n(best.begin(), rays.size(), answers.begin());
        if constexpr (kCount) {
            counts.nodes_visited += object_counts.nodes_visited;
            counts.prims_tested += object_counts.prims_tested;
        }
    }
#endif

    template <bool kAnyHit, bool kCount>
    bool walk(const Ray& ray, InstanceHit& best, TraversalCounters& counts) const {
        if (ray.tnear >= 0.0f) return walk_from<kAnyHit, kCount, true>(ray, best, counts);
        return walk_from<kAnyHit, kCount, false>(ray, best, counts);
    }

    // Whether ray conditioning would leave an object ray as it is (may_need_conditioning against the
    // object's box): a direction in the ordinary range and an origin that is not far.
    [[nodiscard]] static bool is_ordinary(const Ray& ray, const InstanceRecord& record) {
        const float largest = max_component(abs(ray.direction));
        return largest >= kDirectionLowest && largest <= kDirectionHighest &&
               max_component(abs(ray.origin - record.object_centre)) <= record.far_limit;
    }

    // The end of the interval an instance visit traces: the ray's tfar, or once it has a hit, the float
    // after that hit's t (closed). A hit mapped back from a moved origin (ObjectRay::shift) may lie beyond
    // the mapped end of [tnear, best t] and still round to best t: with best t itself as the end, an
    // instance visited after the one that found such a hit would miss it and lose the tie its smaller id
    // wins (lancer::closer; InstancedScene.TiesGoToTheSmallerInstanceIdVisitedSecond). A hit found beyond
    // best t loses to it by lancer::closer, so a ray's answer does not depend on the order of its visits
    // (docs/numerical-contract.md, "Instances").
    [[nodiscard]] static float clipped(const Ray& ray, const InstanceHit& best) {
        return best.hit() ? min_of_numbers(next_float_up(best.t), ray.tfar) : ray.tfar;
    }

    // An instance's object traced with the ray mapped into its frame: true for an any-hit query that found
    // one; for a closest-hit query, `best` improved by the rule of lancer::closer.
    template <bool kAnyHit>
    bool visit(std::uint32_t id, const Ray& ray, InstanceHit& best,
               TraversalCounters* object_counters) const {
        const InstanceRecord& record = records_[id];
        Ray world = ray;
        if constexpr (!kAnyHit) world.tfar = clipped(ray, best);
        const ObjectRay local = record.to_object.to_object(world, record.object_centre, record.far_limit);
        return visit_mapped<kAnyHit>(id, record, world, local, best, object_counters);
    }

    // The rest of a visit, once `world` (the ray, its tfar clipped) is mapped into the object's frame.
    // kCrossing: the object ray is known to go as it is and to cross the object's box (cull_in_lanes).
    template <bool kAnyHit, bool kCrossing = false>
    bool visit_mapped(std::uint32_t id, const InstanceRecord& record, const Ray& world,
                      const ObjectRay& local, InstanceHit& best, TraversalCounters* object_counters) const {
        // Accel's public calls condition their rays first. to_object has moved a far origin near the object
        // already, so a ray with an ordinary direction, into an object seen at its own scale, goes straight
        // to the structure's walk: its one-ray walk where it has one (SingleRayWalk: the batch call's body
        // without its loop, validity test and dispatch), its batch call otherwise (docs/accel/instances.md
        // has the instructions each saves). Such a ray is valid (is_valid): the world ray is, the map in
        // double of its finite components is finite and rounds to floats that is_ordinary bounds (a finite,
        // nonzero direction; an origin within far_limit of the object), and the interval, moved by a finite
        // shift and rounded outwards, keeps tnear <= tfar, tnear >= -FLT_MAX.
        const bool as_is =
            kCrossing || (record.traced->scale_exponent() == 0 && is_ordinary(local.ray, record));
        // An object ray that misses the object's box misses every hit the object holds (the box the top
        // level places, docs/numerical-contract.md, "Instances"): the visit ends before the object's walk
        // sets the ray up. The top level's box is the object's box mapped to the world, axis-aligned around a
        // rotated one, so many visits end here (docs/accel/instances.md, "The visit's overhead, cut").
        if (!kCrossing && as_is && !top_level::crosses(local.ray, record.object_box)) return false;
        if constexpr (kAnyHit) {
            if (as_is && record.walk.any != nullptr)
                return record.walk.any(*record.traced, local.ray, object_counters);
            std::uint8_t occluded = 0;
            if (as_is) {
                record.traced->occluded_batch({&local.ray, 1}, {&occluded, 1}, object_counters);
            } else {
                record.traced->occluded({&local.ray, 1}, {&occluded, 1}, object_counters);
            }
            return occluded != 0;
        } else {
            Hit hit;
            if (as_is && record.walk.closest != nullptr) {
                record.walk.closest(*record.traced, local.ray, hit, object_counters);
            } else if (as_is) {
                record.traced->intersect_batch({&local.ray, 1}, {&hit, 1}, object_counters);
            } else {
                record.traced->intersect({&local.ray, 1}, {&hit, 1}, object_counters);
            }
            if (!hit.hit()) return false;
            // Back to the world's parameter; the interval was rounded outwards, so clamp as restore_t does.
            float t = hit.t;
            if (local.shift != 0.0)
                t = min_of_numbers(
                    max_of_numbers(static_cast<float>(double(hit.t) + local.shift), world.tnear), world.tfar);
            if (closer(t, static_cast<std::int32_t>(id), hit.prim, best)) {
                best = {t,
                        hit.prim,
                        hit.u,
                        hit.v,
                        static_cast<std::int32_t>(id),
                        static_cast<std::int32_t>(record.object)};
            }
            return false;
        }
    }

    // Closest hit (kAnyHit false, into `best`) or any hit (returned) of a valid world ray, front to back as
    // the wide BVH's walk (accel/bvh/bvh_wide_walk.hpp): the 8 child boxes tested at once, the nearest hit
    // child visited and the others pushed, a popped child skipped once it is entered beyond the best hit
    // (closed: an instance entered at exactly the best t may hold a tie that its id wins). kForward: tnear
    // >= 0 (clip_slab).
    template <bool kAnyHit, bool kCount, bool kForward>
    bool walk_from(const Ray& ray, InstanceHit& best, TraversalCounters& counts) const {
        struct StackEntry {
            std::uint32_t child;
            std::uint32_t is_instance;
            float t_entry;
        };
        if (nodes_.empty()) return false;
        const WideRay wide_ray{SlabRay(ray)};
        // Each level pushes at most 7 children, and the wide tree is no deeper than the binary one.
        std::array<StackEntry, (kTopWidth - 1) * BvhAccel::kMaxDepth + 1> stack;
        int stack_size = 0;
        StackEntry current{0, 0, 0.0f};
        TraversalCounters object_counts;
        TraversalCounters* object_counters = kCount ? &object_counts : nullptr;
        bool found = false;
        while (true) {
            if constexpr (kCount) ++counts.nodes_visited;
            if (current.is_instance != 0) {
                if (visit<kAnyHit>(current.child, ray, best, object_counters)) {
                    found = true;
                    break;
                }
            } else {
                const TopNode& node = nodes_[current.child];
                const float t_limit = best.hit() ? best.t : ray.tfar;
                alignas(32) float entry[kTopWidth];
                const unsigned hit_mask =
                    intersect_children<kTopWidth, kForward>(node, wide_ray, ray.tnear, t_limit, entry);
                if (hit_mask != 0) {
                    const int nearest = push_farther_children<kTopWidth>(hit_mask, entry, [&](int slot) {
                        stack[static_cast<std::size_t>(stack_size++)] = {node.child[slot],
                                                                         node.prim_count[slot], entry[slot]};
                    });
                    current = {node.child[nearest], node.prim_count[nearest], entry[nearest]};
                    continue;
                }
            }
            bool popped = false;
            while (stack_size > 0) {
                const StackEntry entry = stack[static_cast<std::size_t>(--stack_size)];
                if (!best.hit() || entry.t_entry <= best.t) {
                    current = entry, popped = true;
                    break;
                }
            }
            if (!popped) break;
        }
        if constexpr (kCount) {
            counts.nodes_visited += object_counts.nodes_visited;
            counts.prims_tested += object_counts.prims_tested;
        }
        return kAnyHit ? found : best.hit();
    }

    const std::vector<TopNode>& nodes_;
    const std::vector<InstanceRecord>& records_;
    float coherent_width_;
    float scene_magnitude_;  // the largest coordinate of the scene's box
};

}  // namespace lancer
