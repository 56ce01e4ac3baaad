// The two-level scene's walk (InstancedScene, lancer/instances.hpp): the top level walked front to back,
// alone or by packets, with each instance's object traced in its frame. What it reads of objects and
// instances is in records.hpp, a packet's rays mapped into an object's frame together in mapped_rays.hpp, the
// scene's building, refit and interface in instanced_scene.cpp. docs/accel/instances.md has the design note.
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
#include "accel/instance/mapped_rays.hpp"
#include "accel/instance/records.hpp"
#include "accel/simd_float.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/accel.hpp"
#include "lancer/instances.hpp"

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
    static constexpr std::size_t kPacketRays = top_level::kPacketRays;
    // Fewer rays than this walk alone: the packet's loading and culls pay for several rays.
    static constexpr std::size_t kFewestPacketRays = 8;
    using RayMask = top_level::RayMask;

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
    // together too, culled from their ends (ends_interval). Eight rays at a time, their fields transposed
    // into lanes: is_valid_ray, SlabRay and the ends lane by lane, in the same fp32 operations. A group that
    // breaks the rules ends the loading at once: incoherent batches (diffuse bounces) pay a group's tests.
    template <bool kAnyHit>
    [[nodiscard]] bool load(std::span<const Ray> rays, Packet& packet) const {
        using Ops = simd::Avx2;
        using Float = Ops::Float;
        constexpr int kLanes = Ops::kWidth;
        const Float infinity = Ops::broadcast(kInfinity), minus_infinity = Ops::broadcast(-kInfinity);
        const Float zero = Ops::broadcast(0.0f), one = Ops::broadcast(1.0f);
        Float origin_lo[3], origin_hi[3], inv_lo[3], inv_hi[3], end_lo[3], end_hi[3], reach[3];
        for (int axis = 0; axis < 3; ++axis) {
            origin_lo[axis] = inv_lo[axis] = end_lo[axis] = infinity;
            origin_hi[axis] = inv_hi[axis] = end_hi[axis] = minus_infinity;
            reach[axis] = zero;
        }
        Float tnear_min = infinity, length = zero;
        Float forward_and_finite = Ops::equal(zero, zero);  // every valid ray: tnear >= 0, a finite end
        std::array<RayMask, 3> negative{};
        packet.valid = 0;
        alignas(32) Ray padded[kLanes];
        for (std::size_t first = 0; first < kPacketRays; first += kLanes) {
            // A partial group is padded with rays of zero direction, which are invalid.
            const Ray* source = rays.data() + first;
            if (first + kLanes > rays.size()) {
                for (std::size_t k = 0; k < kLanes; ++k)
                    padded[k] = first + k < rays.size() ? rays[first + k] : Ray{{}, {}, 0.0f, 0.0f};
                source = padded;
            }
            Float fields[8];
            static_assert(sizeof(Ray) == 8 * sizeof(float));
            Ops::load_fields8(&source->origin.x, fields);
            const Float origin[3] = {fields[0], fields[1], fields[2]};
            const Float direction[3] = {fields[3], fields[4], fields[5]};
            const Float tnear = fields[6], tfar = fields[7];
            const Float valid = valid_ray_lanes<Ops>(fields);  // is_valid_ray's answer
            const unsigned valid_lanes = Ops::bits(valid);
            packet.valid |= static_cast<RayMask>(valid_lanes) << first;
            for (std::size_t axis = 0; axis < 3; ++axis) {
                const Float inv_direction = Ops::div(one, direction[axis]);  // SlabRay
                if ((Ops::bits(Ops::less(Ops::abs(inv_direction), infinity)) & valid_lanes) != valid_lanes)
                    return false;
                negative[axis] |= static_cast<RayMask>(Ops::sign_bits(direction[axis]) & valid_lanes)
                                  << first;
                // Every valid ray so far has the sign of the first: its bit set in all or none of them.
                if (negative[axis] != 0 && negative[axis] != packet.valid) return false;
                origin_lo[axis] = Ops::min(Ops::select(valid, origin[axis], infinity), origin_lo[axis]);
                origin_hi[axis] = Ops::max(Ops::select(valid, origin[axis], minus_infinity), origin_hi[axis]);
                inv_lo[axis] = Ops::min(Ops::select(valid, inv_direction, infinity), inv_lo[axis]);
                inv_hi[axis] = Ops::max(Ops::select(valid, inv_direction, minus_infinity), inv_hi[axis]);
                Ops::store(&packet.origin[axis][first], Ops::select(valid, origin[axis], zero));
                Ops::store(&packet.inv_direction[axis][first], Ops::select(valid, inv_direction, one));
                if constexpr (kAnyHit) {
                    const Float along = Ops::mul(direction[axis], tfar);
                    const Float end = Ops::add(origin[axis], along);
                    forward_and_finite = Ops::mask_and(
                        forward_and_finite,
                        Ops::select(valid, Ops::less(Ops::abs(end), infinity), forward_and_finite));
                    end_lo[axis] = Ops::min(Ops::select(valid, end, infinity), end_lo[axis]);
                    end_hi[axis] = Ops::max(Ops::select(valid, end, minus_infinity), end_hi[axis]);
                    reach[axis] = Ops::max(Ops::select(valid, Ops::abs(along), zero), reach[axis]);
                }
            }
            if constexpr (kAnyHit) {
                forward_and_finite =
                    Ops::mask_and(forward_and_finite,
                                  Ops::select(valid, Ops::greater_equal(tnear, zero), forward_and_finite));
                length = Ops::max(Ops::select(valid, Ops::sub(tfar, tnear), zero), length);
            }
            const Float lane_tnear = Ops::select(valid, tnear, infinity);
            tnear_min = Ops::min(lane_tnear, tnear_min);
            Ops::store(&packet.tnear[first], lane_tnear);
            Ops::store(&packet.tlimit[first], Ops::select(valid, tfar, minus_infinity));
        }
        if (packet.valid == 0) return false;
        Box3f origins, ends, reciprocals;
        Vec3f reached;
        for (std::size_t axis = 0; axis < 3; ++axis) {
            const auto a = static_cast<int>(axis);
            origins.lo[a] = Ops::reduce_min(origin_lo[axis]);
            origins.hi[a] = Ops::reduce_max(origin_hi[axis]);
            reciprocals.lo[a] = Ops::reduce_min(inv_lo[axis]);
            reciprocals.hi[a] = Ops::reduce_max(inv_hi[axis]);
            ends.lo[a] = Ops::reduce_min(end_lo[axis]);
            ends.hi[a] = Ops::reduce_max(end_hi[axis]);
            reached[a] = Ops::reduce_max(reach[axis]);
            packet.near_side[axis] = negative[axis] != 0 ? TopNode::kHi : TopNode::kLo;
        }
        packet.from_ends = max_component(origins.extent()) > coherent_width_;
        if (packet.from_ends) {
            const bool ends_together = kAnyHit && Ops::bits(forward_and_finite) == (1u << kLanes) - 1 &&
                                       max_component(ends.extent()) <= coherent_width_;
            if (!ends_together) return false;
            ends_interval(packet, ends, reciprocals, reached, Ops::reduce_max(length));
            return true;
        }
        packet.interval.near_side = packet.near_side;
        for (std::size_t axis = 0; axis < 3; ++axis) {
            const auto a = static_cast<int>(axis);
            packet.interval.set_axis(axis, origins.lo[a], origins.hi[a], reciprocals.lo[a],
                                     reciprocals.hi[a]);
        }
        packet.interval.tnear_min = Ops::reduce_min(tnear_min);
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

    // The largest box test limit of the packet's rays, where the cull stops: a lane left out (invalid, or
    // past the packet's rays) has -inf, which never wins; the walk asks while every valid ray is alive.
    [[nodiscard]] static float largest_limit(const Packet& packet) {
        using Ops = simd::Avx2;
        Ops::Float largest = Ops::load(packet.tlimit);
        for (std::size_t first = Ops::kWidth; first < kPacketRays; first += Ops::kWidth)
            largest = Ops::max(Ops::load(&packet.tlimit[first]), largest);
        return Ops::reduce_max(largest);
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
        top_level::MappedRays mapped;
        float limit_max = packet.from_ends ? packet.ends_limit : largest_limit(packet);
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
                const int mapped_count = top_level::map_together(
                    records_[child], rays, met,
                    [&](int i) {
                        const Ray& ray = rays[static_cast<std::size_t>(i)];
                        return kAnyHit ? ray.tfar : clipped(ray, best[static_cast<std::size_t>(i)]);
                    },
                    mapped);
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
                    limit_max = largest_limit(packet);
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
            kCrossing || (record.traced->scale_exponent() == 0 && top_level::is_ordinary(local.ray, record));
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
        // Each level pushes at most 7 children, and the wide tree is no deeper than the binary one;
        // push_farther_children's uncounted write lands where the node's first push would.
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
                    const int nearest =
                        push_farther_children<kTopWidth>(hit_mask, entry, [&](int slot, bool counted) {
                            stack[static_cast<std::size_t>(stack_size)] = {
                                node.child[slot], node.prim_count[slot], entry[slot]};
                            stack_size += counted ? 1 : 0;
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
