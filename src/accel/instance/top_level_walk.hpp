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
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/instance/affine.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/accel.hpp"
#include "lancer/instances.hpp"

namespace lancer::top_level {

struct ObjectRecord {
    std::shared_ptr<const Accel> structure;
    // What the walk traces: the structure, or the single-ray structure a packet structure holds.
    const Accel* traced = nullptr;
    // The triangles the scene flattened, when it built the object itself.
    std::shared_ptr<const std::vector<Triangle>> triangles;
    std::size_t primitives = 0;
};

// What the walk reads of an instance: 144 bytes.
struct InstanceRecord {
    InverseAffine to_object;
    const Accel* traced = nullptr;
    std::uint32_t object = 0;
    // Ray conditioning's far-origin frame of the object's box (FarOriginFrame): its centre, and the distance
    // beyond which an origin is far.
    Vec3f object_centre;
    float far_limit = kInfinity;
};

// The top level's nodes: the wide BVH's (accel/bvh/bvh_wide.hpp), 8 children tested at once.
constexpr int kTopWidth = 8;
using TopNode = WideBvhNode<kTopWidth>;

}  // namespace lancer::top_level

namespace lancer {

// The walk of a committed top level over `nodes` and `records` (InstancedScene::State's), with `batched`, by
// object, the structure that traces a group of rays (a packet structure itself, where `traced` is the
// single-ray structure it holds). A member of InstancedScene, for Accel's batch calls on the objects (its
// friend's).
class InstancedScene::Walk {
    using TopNode = top_level::TopNode;
    using InstanceRecord = top_level::InstanceRecord;
    static constexpr int kTopWidth = top_level::kTopWidth;

  public:
    Walk(const std::vector<TopNode>& nodes, const std::vector<InstanceRecord>& records,
         const std::vector<const Accel*>& batched)
        : nodes_(nodes), records_(records), batched_(batched) {}

    // The conditioned rays cut into groups of kGroupSize consecutive rays, each group walked together
    // (walk_group); answers[i] the closest hit (InstanceHit) or whether the ray is occluded (std::uint8_t,
    // kAnyHit). Invalid rays miss. A ray that starts behind its origin (tnear < 0), which the group's box
    // test does not take, and the rays of a group with fewer than kFewestGrouped such rays, walk alone.
    // Every ray gets the answer of its own walk, bit for bit: the answer does not depend on the order in
    // which its instances are visited (`clipped`).
    template <bool kAnyHit, class Answer>
    void trace(std::span<const Ray> traced, std::span<Answer> answers, TraversalCounters* counters) const {
        const auto trace = [&]<bool kCount>() {
            TraversalCounters counts;
            Group group;
            for (std::size_t first = 0; first < traced.size(); first += kGroupSize) {
                const std::size_t end = std::min(traced.size(), first + kGroupSize);
                group.clear();
                for (std::size_t i = first; i < end; ++i) {
                    answers[i] = Answer{};
                    if (!is_valid(traced[i])) continue;
                    if (traced[i].tnear < 0.0f) {
                        walk_alone<kAnyHit, kCount>(traced[i], answers[i], counts);
                        continue;
                    }
                    group.add(traced[i], static_cast<std::uint32_t>(i));
                }
                if (group.size >= kFewestGrouped) {
                    walk_group<kAnyHit, kCount>(group, counts);
                    group.store<kAnyHit>(answers);
                    continue;
                }
                for (int k = 0; k < group.size; ++k) {
                    const std::uint32_t i = group.index[static_cast<std::size_t>(k)];
                    walk_alone<kAnyHit, kCount>(traced[i], answers[i], counts);
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
    // Rays walked together: the bits of a mask, and the 8x8 tile of the bench's primary rays.
    static constexpr int kGroupSize = 64;
    using RayBits = std::uint64_t;
    // The fewest valid rays a group walks with: below, each ray's own walk costs less than the group's
    // bookkeeping.
    static constexpr int kFewestGrouped = 4;
    // The fewest rays at an instance that go to the object's batch structure (`batched_`): fewer go to its
    // single-ray structure, which its packets would hand them to anyway.
    static constexpr int kFewestBatched = 4;

    // A group's rays: each one's slab ray, interval and closest hit so far (or whether it is still
    // unoccluded).
    struct Group {
        int size = 0;
        std::array<std::uint32_t, kGroupSize> index;  // in the batch
        std::array<const Ray*, kGroupSize> ray;
        std::array<std::optional<WideRay>, kGroupSize> wide;
        alignas(32) std::array<float, kGroupSize> tlimit;  // tfar, or the closest hit so far
        std::array<InstanceHit, kGroupSize> best;
        RayBits alive = 0;  // the rays not yet occluded (kAnyHit); all of them otherwise
        // An instance visit's scratch (visit_group): the rays mapped into the object's frame, each one's
        // shift and lane, and the object's answers.
        std::array<Ray, kGroupSize> local_rays;
        std::array<double, kGroupSize> shifts;
        std::array<int, kGroupSize> lanes;
        std::array<Hit, kGroupSize> hits;
        std::array<std::uint8_t, kGroupSize> occluded;

        void clear() { size = 0, alive = 0; }
        void add(const Ray& traced, std::uint32_t i) {
            const auto k = static_cast<std::size_t>(size);
            index[k] = i, ray[k] = &traced;
            wide[k].emplace(SlabRay(traced));
            tlimit[k] = traced.tfar;
            best[k] = InstanceHit{};
            alive |= RayBits{1} << size++;
        }
        template <bool kAnyHit, class Answer>
        void store(std::span<Answer> answers) {
            for (int k = 0; k < size; ++k) {
                const auto slot = static_cast<std::size_t>(k);
                if constexpr (kAnyHit) {
                    answers[index[slot]] = ((alive >> k) & 1u) == 0 ? 1 : 0;
                } else {
                    answers[index[slot]] = best[slot];
                }
            }
        }
    };

    template <bool kAnyHit, bool kCount, class Answer>
    void walk_alone(const Ray& ray, Answer& answer, TraversalCounters& counts) const {
        InstanceHit best;
        const bool found = walk<kAnyHit, kCount>(ray, best, counts);
        if constexpr (kAnyHit) {
            answer = found;
        } else {
            answer = best;
        }
    }

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
    // after that hit's t. An instance's hit can then only win (lancer::closer) by a t that it reports
    // whatever hit came first: mapped back from a moved origin (ObjectRay::shift), a t' beyond the mapped
    // end of [tnear, best t] may round to best t, and that hit, found with this end, then ties by instance
    // id as it would have had the instance come first. So the answer is the same in any order of visits,
    // the single ray's and a group's (docs/accel/instances.md, "Groups of rays").
    [[nodiscard]] static float clipped(const Ray& ray, const InstanceHit& best) {
        return best.hit() ? std::fmin(std::nextafter(best.t, kInfinity), ray.tfar) : ray.tfar;
    }

    // An object's hit of the world ray `world` mapped as `local`, back in the world's parameter and kept
    // in `best` by the rule of lancer::closer.
    static void merge(std::uint32_t id, const InstanceRecord& record, const Ray& world,
                      const ObjectRay& local, const Hit& hit, InstanceHit& best) {
        if (!hit.hit()) return;
        // The interval was rounded outwards, so clamp as restore_t does.
        float t = hit.t;
        if (local.shift != 0.0)
            t = std::fmin(std::fmax(static_cast<float>(double(hit.t) + local.shift), world.tnear),
                          world.tfar);
        if (closer(t, static_cast<std::int32_t>(id), hit.prim, best)) {
            best = {t,
                    hit.prim,
                    hit.u,
                    hit.v,
                    static_cast<std::int32_t>(id),
                    static_cast<std::int32_t>(record.object)};
        }
    }

    // Accel's public calls condition their rays first. to_object has moved a far origin near the object
    // already, so a ray with an ordinary direction, into an object seen at its own scale, goes straight to
    // the structure's batch call, 5% fewer instructions on the views of 1,000 bunnies
    // (docs/accel/instances.md).
    [[nodiscard]] static bool as_is(const ObjectRay& local, const InstanceRecord& record) {
        return record.traced->scale_exponent() == 0 && is_ordinary(local.ray, record);
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
        const bool direct = as_is(local, record);
        if constexpr (kAnyHit) {
            std::uint8_t occluded = 0;
            if (direct) {
                record.traced->occluded_batch({&local.ray, 1}, {&occluded, 1}, object_counters);
            } else {
                record.traced->occluded({&local.ray, 1}, {&occluded, 1}, object_counters);
            }
            return occluded != 0;
        } else {
            Hit hit;
            if (direct) {
                record.traced->intersect_batch({&local.ray, 1}, {&hit, 1}, object_counters);
            } else {
                record.traced->intersect({&local.ray, 1}, {&hit, 1}, object_counters);
            }
            merge(id, record, world, local, hit, best);
            return false;
        }
    }

    // The group's `rays` at instance `id`, each clipped and mapped into the object's frame as `visit` maps
    // it. Those that go as they are (as_is) are traced by batch calls: the rays that still start at their
    // origin (tnear >= 0: the origin was near enough not to be moved) on the object's batch structure once
    // kFewestBatched of them arrive together (a packet structure's packets or streams, which take no other
    // rays), the others on its single-ray structure. The rest go one by one through the public call.
    template <bool kAnyHit>
    void visit_group(std::uint32_t id, RayBits rays, Group& group, TraversalCounters* object_counters) const {
        const InstanceRecord& record = records_[id];
        // Forward rays from the front of the scratch arrays, the others from the back.
        std::size_t forward = 0, backward = kGroupSize;
        for (RayBits rest = rays; rest != 0; rest &= rest - 1) {
            const int k = std::countr_zero(rest);
            const auto slot = static_cast<std::size_t>(k);
            Ray world = *group.ray[slot];
            if constexpr (!kAnyHit) world.tfar = clipped(world, group.best[slot]);
            const ObjectRay local = record.to_object.to_object(world, record.object_centre, record.far_limit);
            if (!as_is(local, record)) {
                if (visit<kAnyHit>(id, *group.ray[slot], group.best[slot], object_counters))
                    group.alive &= ~(RayBits{1} << k);
                continue;
            }
            const std::size_t at = local.ray.tnear >= 0.0f ? forward++ : --backward;
            group.local_rays[at] = local.ray, group.shifts[at] = local.shift, group.lanes[at] = k;
        }
        if (forward >= kFewestBatched) {
            trace_object<kAnyHit>(id, *batched_[record.object], 0, forward, group, object_counters);
        } else {
            trace_object<kAnyHit>(id, *record.traced, 0, forward, group, object_counters);
        }
        trace_object<kAnyHit>(id, *record.traced, backward, kGroupSize, group, object_counters);
        if constexpr (!kAnyHit) {
            for (RayBits rest = rays; rest != 0; rest &= rest - 1) {
                const auto slot = static_cast<std::size_t>(std::countr_zero(rest));
                if (group.best[slot].hit()) group.tlimit[slot] = group.best[slot].t;
            }
        }
    }

    // The group's mapped rays [from, to) of its scratch arrays through `structure`'s batch call at instance
    // `id`, their answers kept.
    template <bool kAnyHit>
    void trace_object(std::uint32_t id, const Accel& structure, std::size_t from, std::size_t to,
                      Group& group, TraversalCounters* object_counters) const {
        if (from == to) return;
        const std::span<const Ray> traced(group.local_rays.data() + from, to - from);
        if constexpr (kAnyHit) {
            structure.occluded_batch(traced, {group.occluded.data() + from, traced.size()}, object_counters);
            for (std::size_t at = from; at < to; ++at) {
                if (group.occluded[at] != 0) group.alive &= ~(RayBits{1} << group.lanes[at]);
            }
        } else {
            structure.intersect_batch(traced, {group.hits.data() + from, traced.size()}, object_counters);
            const InstanceRecord& record = records_[id];
            for (std::size_t at = from; at < to; ++at) {
                if (!group.hits[at].hit()) continue;
                const auto slot = static_cast<std::size_t>(group.lanes[at]);
                InstanceHit& best = group.best[slot];
                Ray world = *group.ray[slot];
                world.tfar = clipped(world, best);
                merge(id, record, world, {group.local_rays[at], group.shifts[at]}, group.hits[at], best);
            }
        }
    }

    // The group's rays walked together over the top level, as bvh8_packet's ray streams walk bvh8
    // (accel/bvh/bvh8_packet_stream.hpp): at an inner node each ray that reached it tests the 8 child boxes
    // with its own walk's test (intersect_children, clipped at its closest hit so far), and each hit child is
    // visited once for the rays that hit it, nearest first by the least entry of its rays. A popped instance
    // is tested again against each of its rays' closest hit, which may have come nearer since it was pushed
    // (the single walk's skip of an instance entered beyond the best hit). kAnyHit: a ray leaves the group
    // at its first hit.
    template <bool kAnyHit, bool kCount>
    void walk_group(Group& group, TraversalCounters& counts) const {
        struct StackEntry {
            const TopNode* parent;
            int slot;
            RayBits rays;
            std::uint32_t visits;  // instance visits before the push: none since, no closest hit has moved
        };
        if (nodes_.empty()) return;
        std::array<StackEntry, (kTopWidth - 1) * BvhAccel::kMaxDepth + kTopWidth> stack;
        int stack_size = 0;
        TraversalCounters object_counts;
        TraversalCounters* object_counters = kCount ? &object_counts : nullptr;
        const TopNode* node = &nodes_[0];
        RayBits rays = group.alive;
        std::uint32_t visits = 0;
        while (true) {
            // INNER: each ray against the 8 children; the children hit by any pushed, the nearest on top.
            if constexpr (kCount) counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(rays));
            std::array<RayBits, kTopWidth> child_rays{};
            alignas(32) float nearest[kTopWidth];
            std::fill(std::begin(nearest), std::end(nearest), kInfinity);
            unsigned hit_children = 0;
            for (RayBits rest = rays; rest != 0; rest &= rest - 1) {
                const int k = std::countr_zero(rest);
                const auto slot = static_cast<std::size_t>(k);
                alignas(32) float entry[kTopWidth];
                const unsigned hit = children_hit(*node, group, slot, entry);
                hit_children |= hit;
                for (unsigned each = hit; each != 0; each &= each - 1) {
                    const int child = std::countr_zero(each);
                    child_rays[static_cast<std::size_t>(child)] |= RayBits{1} << k;
                    // Entry distances are never NaN (intersect_children's NaN rule): no need for fmin's.
                    nearest[child] = entry[child] < nearest[child] ? entry[child] : nearest[child];
                }
            }
            std::array<int, kTopWidth> order;
            const int hit_count = order_by_entry<kTopWidth>(hit_children, nearest, order);
            for (int k = hit_count - 1; k >= 0; --k) {
                const int slot = order[static_cast<std::size_t>(k)];
                stack[static_cast<std::size_t>(stack_size++)] = {
                    node, slot, child_rays[static_cast<std::size_t>(slot)], visits};
            }
            // POP until an inner child with rays in it, visiting the instances on the way.
            while (true) {
                if (stack_size == 0) {
                    if constexpr (kCount) {
                        counts.nodes_visited += object_counts.nodes_visited;
                        counts.prims_tested += object_counts.prims_tested;
                    }
                    return;
                }
                const StackEntry popped = stack[static_cast<std::size_t>(--stack_size)];
                rays = popped.rays & group.alive;
                if (rays == 0) continue;
                const std::uint32_t child = popped.parent->child[popped.slot];
                if (popped.parent->prim_count[popped.slot] == 0) {
                    node = &nodes_[child];
                    break;
                }
                if (!kAnyHit && popped.visits != visits)
                    rays = still_entered(*popped.parent, popped.slot, rays, group);
                if (rays == 0) continue;
                if constexpr (kCount) counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(rays));
                visit_group<kAnyHit>(child, rays, group, object_counters);
                ++visits;
                if (kAnyHit && group.alive == 0) {
                    stack_size = 0;
                }
            }
        }
    }

    // The children of `node` that the group's ray `at` enters before its closest hit so far, as its own
    // walk tests them, with their entry distances.
    [[nodiscard]] static unsigned children_hit(const TopNode& node, const Group& group, std::size_t at,
                                               float (&entry)[kTopWidth]) {
        return intersect_children<kTopWidth, true>(node, *group.wide[at], group.ray[at]->tnear,
                                                   group.tlimit[at], entry);
    }

    // Those of `rays` that still enter child `slot` of `parent` before their closest hit so far.
    [[nodiscard]] static RayBits still_entered(const TopNode& parent, int slot, RayBits rays,
                                               const Group& group) {
        RayBits entered = 0;
        for (RayBits rest = rays; rest != 0; rest &= rest - 1) {
            const int k = std::countr_zero(rest);
            const auto at = static_cast<std::size_t>(k);
            alignas(32) float entry[kTopWidth];
            if (((children_hit(parent, group, at, entry) >> slot) & 1u) != 0) entered |= RayBits{1} << k;
        }
        return entered;
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
                    std::array<int, kTopWidth> order;
                    const int hit_count = order_by_entry<kTopWidth>(hit_mask, entry, order);
                    for (int k = hit_count - 1; k > 0; --k) {
                        const int slot = order[static_cast<std::size_t>(k)];
                        stack[static_cast<std::size_t>(stack_size++)] = {node.child[slot],
                                                                         node.prim_count[slot], entry[slot]};
                    }
                    const int nearest = order[0];
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
    const std::vector<const Accel*>& batched_;
};

}  // namespace lancer
