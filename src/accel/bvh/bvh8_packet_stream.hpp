// bvh8_packet's ray streams (docs/accel/stream.md): the rays of a batch that the interval cull cannot take
// are sorted, as they come, into streams of up to 64 rays (32 with the AVX2 kernels) whose reciprocal
// directions share their signs, and each stream walks bvh8 depth first as a whole. At an inner node every ray
// of the stream that reached it tests the node's 8 child boxes on its own, with bvh8's box test; the rays
// that hit each child are kept as a bit mask beside it, and a child is visited once for all of them. This is
// the stream traversal Embree's rtcOccluded1M runs on the octant-sorted streams it cuts a call into (Embree
// 3's BVHNIntersectorStream), its fastest call on shadow rays: a node is fetched once per stream, and a
// ray's box test needs neither a sort of the children nor a stack of its own. For closest hits the children
// go nearest first along the octant's diagonal, one order for the stream, and each ray's boxes are clipped
// at its closest hit so far; for occlusion they go in slot order, and a ray leaves its stream at its first
// hit. Each ray's box tests are clip_slab's, as in bvh8's walk, against a limit never below its final hit,
// and its leaves are tested with bvh8's triangle blocks, so every ray gets bvh8's answer bit for bit.
// Included by the packet kernel's source alone (bvh8_packet_kernel.cpp).
#pragma once

#include <immintrin.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <type_traits>
#include <vector>

#include "accel/bvh/bvh8_packet_rays.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/bvh_wide_walk.hpp"
#include "accel/bvh/triangle_block.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/simd_float.hpp"
#include "core/isa_namespace.hpp"

#if defined(__AVX2__)
namespace lancer {
inline namespace LANCER_ISA_NAMESPACE {
namespace {

// Where a ray of a batch goes (RayStreams::add), read off its 8 fields in one register: is_valid's tests
// lane by lane, and the octant from the direction's sign bits. kInvalid: the ray misses; kBehind: tnear < 0,
// the ray walks alone; otherwise the octant, bit a set where direction component a has its sign bit set. The
// reciprocal, whose sign picks the side by which the ray enters every box on that axis
// (WideRay::entry_side), has the same sign bit for every non-NaN component, zeros and denormals included
// (1 / -0 = -inf), so the divisions wait for the stream.
constexpr int kInvalid = -1;
constexpr int kBehind = 8;
[[nodiscard]] inline int stream_entry(const Ray& ray) {
    static_assert(sizeof(Ray) == 8 * sizeof(float) && offsetof(Ray, tfar) == 7 * sizeof(float));
    const __m256 fields = _mm256_loadu_ps(&ray.origin.x);
    // NaN compares false: `|x| < inf` is isfinite. The origin, the direction and tnear must be finite.
    const __m256 magnitude = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), fields);
    const auto finite = static_cast<unsigned>(
        _mm256_movemask_ps(_mm256_cmp_ps(magnitude, _mm256_set1_ps(kInfinity), _CMP_LT_OQ)));
    const auto nonzero =
        static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(fields, _mm256_setzero_ps(), _CMP_NEQ_UQ)));
    // tnear <= tfar is false when tfar is NaN: is_valid's `tfar == tfar` with it.
    if ((finite & 0x7fu) != 0x7fu || (nonzero & 0x38u) == 0 || !(ray.tnear <= ray.tfar)) return kInvalid;
    if (ray.tnear < 0.0f) return kBehind;
    return static_cast<int>((static_cast<unsigned>(_mm256_movemask_ps(fields)) >> 3) & 7u);
}

// The rays that hit each of a node's 8 children, one bit per ray of the stream: 8 x 64 bits in one AVX-512
// register, where a compare's mask ORs a ray's bit into the hit children at once; 8 x 32 bits with AVX2.
#if defined(__AVX512F__) && defined(__AVX512VL__)
struct ChildRays {
    using Bits = std::uint64_t;
    __m512i rays = _mm512_setzero_si512();

    // The children whose interval [t0, t1] is not empty gain `ray`.
    void add(int ray, __m256 t0, __m256 t1) {
        const __mmask8 children = _mm256_cmp_ps_mask(t0, t1, _CMP_LE_OQ);
        rays = _mm512_mask_or_epi64(rays, children, rays, _mm512_set1_epi64(std::int64_t{1} << ray));
    }
    unsigned store(Bits* out) const {
        _mm512_storeu_si512(out, rays);
        return _mm512_test_epi64_mask(rays, rays);
    }
};
#else
struct ChildRays {
    using Bits = std::uint32_t;
    __m256i rays = _mm256_setzero_si256();

    void add(int ray, __m256 t0, __m256 t1) {
        const __m256i hit = _mm256_castps_si256(_mm256_cmp_ps(t0, t1, _CMP_LE_OQ));
        rays = _mm256_or_si256(rays, _mm256_and_si256(hit, _mm256_set1_epi32(static_cast<int>(1u << ray))));
    }
    unsigned store(Bits* out) const {
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), rays);
        const __m256i missed = _mm256_cmpeq_epi32(rays, _mm256_setzero_si256());
        return ~static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(missed))) & 0xffu;
    }
};
#endif

// One stream: kAnyHit, occlusion (answers std::uint8_t); otherwise closest hits (Hit).
template <class TriangleTestT, bool kAnyHit>
class RayStream {
  public:
    static constexpr int kCapacity = 8 * static_cast<int>(sizeof(ChildRays::Bits));
    using Answer = std::conditional_t<kAnyHit, std::uint8_t, Hit>;

    RayStream(const Bvh8Accel& bvh, const Geometry& geometry)
        : nodes_(bvh.nodes()), blocks_(bvh.blocks()), geometry_(geometry) {}

    // Traces rays[index[k]] for k < count <= kCapacity, each valid, with tnear >= 0 and in `octant`
    // (stream_entry), into answers[index[k]].
    template <bool kCount>
    void trace(std::span<const Ray> rays, const std::uint32_t* index, int count, unsigned octant,
               std::span<Answer> answers, TraversalCounters& counts) {
        load(rays, index, count);
        if (!nodes_.empty()) {
            Stack stack;
            WalkState walk;
            begin(octant, walk);
            while (walk_step<kCount, false>(walk, stack, counts)) {
            }
        }
        finish(answers);
    }

    // trace() in three parts, so that several streams can take turns a node at a time (RayStreams): start
    // loads the rays, step visits one node or leaf and requests the lines of the next (false once the walk
    // is over), finish writes the answers.
    void start(std::span<const Ray> rays, const std::uint32_t* index, int count, unsigned octant) {
        load(rays, index, count);
        begin(octant, walk_);
        done_ = nodes_.empty();
    }

    template <bool kCount>
    bool step(TraversalCounters& counts) {
        if (done_) return false;
        done_ = !walk_step<kCount, true>(walk_, stack_, counts);
        return !done_;
    }

    void finish(std::span<Answer> answers) const {
        for (int k = 0; k < count_; ++k) {
            if constexpr (kAnyHit) {
                answers[index_[k]] = ((alive_ >> k) & 1u) == 0 ? 1 : 0;
            } else {
                answers[index_[k]] = best_[k];
            }
        }
    }

  private:
    using RayBits = ChildRays::Bits;
    using Ops = simd::Avx2;
    using ChildRef = wide_walk::ChildRef;
    struct Entry {
        ChildRef ref;
        RayBits rays;
    };
    using Stack = std::array<Entry, wide_walk::kStackSize<kWidth>>;
    // Where the walk stands, beside its stack: locals of trace(), or members (walk_, stack_) between the
    // steps of a stream in flight. Apart from the stack, so that trace()'s stay in registers.
    struct WalkState {
        int stack_size = 0;
        ChildRef current{0, 0};
        RayBits rays = 0;
        std::array<int, 3> side{};
        // -0.0f on the axes the octant enters by the high side, whose planes the diagonal order subtracts.
        Ops::Float diagonal_sign[3];
    };

    void load(std::span<const Ray> rays, const std::uint32_t* index, int count) {
        count_ = count;
        for (int k = 0; k < count; ++k) {
            index_[k] = index[k];
            const Ray& ray = rays[index[k]];
            const SlabRay slab(ray);
            for (int axis = 0; axis < 3; ++axis)
                origin_[axis][k] = slab.origin[axis], inv_direction_[axis][k] = slab.inv_direction[axis];
            tnear_[k] = ray.tnear, tlimit_[k] = ray.tfar;
            // Made for every ray when the stream starts: a secondary ray starts on a surface, so nearly
            // every one reaches a leaf, and a branch at each ray's first leaf was mispredicted.
            prepared_[static_cast<std::size_t>(k)].emplace(ray);
            block_rays_[static_cast<std::size_t>(k)].emplace(*prepared_[static_cast<std::size_t>(k)],
                                                             geometry_);
            if constexpr (!kAnyHit) best_[k] = Hit{};
        }
        alive_ = count == kCapacity ? ~RayBits{0} : (RayBits{1} << count) - 1;
    }

    void begin(unsigned octant, WalkState& walk) const {
        for (int axis = 0; axis < 3; ++axis) {
            walk.side[static_cast<std::size_t>(axis)] = (octant >> axis) & 1;
            walk.diagonal_sign[axis] = Ops::broadcast(std::bit_cast<float>(((octant >> axis) & 1u) << 31));
        }
        walk.stack_size = 0;
        walk.current = {0, 0};
        walk.rays = alive_;
    }

    // One node or leaf of the stream's walk, then the move to the next child; false once no child is left.
    // kRequestNext: the next child's lines are requested, for a stream in flight, which visits it after the
    // other streams' turns.
    template <bool kCount, bool kRequestNext>
    [[gnu::always_inline]] bool walk_step(WalkState& walk, Stack& stack, TraversalCounters& counts) {
        if (walk.current.prim_count > 0) {
            test_leaf<kCount>(walk.current, walk.side, walk.rays & alive_, counts);
            if (kAnyHit && alive_ == 0) return false;
        } else {
            if constexpr (kCount)
                counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(walk.rays));
            const Node& node = nodes_[walk.current.child];
            alignas(32) float along[kWidth];
            const unsigned hit_children =
                test_children(node, walk.side, walk.diagonal_sign, walk.rays, along);
            if (hit_children != 0) {
                const auto push = [&](int slot) {
                    const ChildRef child{node.child[slot], node.prim_count[slot]};
                    stack[static_cast<std::size_t>(walk.stack_size++)] = {child, child_rays_[slot]};
                    // Fetched while the stream walks the child's siblings (docs/accel/stream.md).
                    wide_walk::prefetch_child<kWidth>(nodes_, blocks_, child.child, child.prim_count);
                };
                // Closest hits: nearest first along the octant's diagonal, a stand-in for each ray's own
                // entry order that the whole stream shares; the others pushed farthest first. Occlusion:
                // slot order, as bvh8's any-hit walk and the occlusion packets, since any hit ends a ray
                // (docs/log/stream.md, "Occlusion streams in slot order").
                std::array<int, 2 * kWidth> order;
                const int hit_count =
                    kAnyHit ? order_by_slot(hit_children, order) : order_by_rank(hit_children, along, order);
                for (int k = hit_count - 1; k > 0; --k)
                    push(order[static_cast<std::size_t>(k)]);
                const int first = order[0];
                walk.current = {node.child[first], node.prim_count[first]};
                walk.rays = child_rays_[first];
                if constexpr (kRequestNext)
                    wide_walk::prefetch_child<kWidth>(nodes_, blocks_, walk.current.child,
                                                      walk.current.prim_count);
                return true;
            }
        }
        // POP the next child that some ray still in the stream reached. (A ray whose closest hit has come
        // nearer than the child is dropped there by its box tests, or its block tests find nothing closer.)
        while (true) {
            if (walk.stack_size == 0) return false;
            const Entry& popped = stack[static_cast<std::size_t>(--walk.stack_size)];
            walk.rays = popped.rays & alive_;
            if (walk.rays == 0) continue;
            walk.current = popped.ref;
            return true;
        }
    }

    // Every ray of `rays` against the node's 8 boxes (intersect_children's arithmetic, the entry planes
    // chosen once for the octant, each ray clipped at its tlimit): child_rays_[slot] gets the rays that hit
    // the child; returns the children hit by any. along[slot], for closest hits: how far along the octant's
    // diagonal the child's entry corner lies (the walk's order).
    [[nodiscard, gnu::always_inline]] unsigned test_children(const Node& node, const std::array<int, 3>& side,
                                                             const Ops::Float (&diagonal_sign)[3],
                                                             RayBits rays, float* along) {
        Ops::Float near_bound[3], far_bound[3];
        load_bounds(&node.bounds[0][0][0], side, near_bound, far_bound);
        if constexpr (!kAnyHit) {
            Ops::Float distance = Ops::broadcast(0.0f);
            for (int axis = 0; axis < 3; ++axis) {
                // The plane added, or subtracted (added with its sign bit flipped, the same float) where the
                // octant enters by the high side: a branch on the side here was mispredicted.
                distance = Ops::add(distance, Ops::bit_xor(near_bound[axis], diagonal_sign[axis]));
            }
            Ops::store(along, distance);
        }
        ChildRays hit_rays;
        for (RayBits rest = rays; rest != 0; rest &= rest - 1) {
            const int k = std::countr_zero(rest);
            Ops::Float t0 = Ops::broadcast(tnear_[k]), t1 = Ops::broadcast(tlimit_[k]);
            clip_ray(k, near_bound, far_bound, t0, t1);
            hit_rays.add(k, t0, t1);
        }
        return hit_rays.store(child_rays_.data());
    }

    // The hit children nearest first along the diagonal, equal distances in slot order (order_by_entry's
    // order), into order[0, count), count returned: each child's place is the number of hit children before
    // it, counted in lanes, so no branch depends on the distances (order_by_entry's insertion sort was
    // mispredicted, docs/accel/stream.md). A missed child's place is past the eighth; a NaN distance counts
    // as -inf, so the places of the hit children stay distinct.
    [[nodiscard, gnu::always_inline]] static int order_by_rank(unsigned hit_children, const float* along,
                                                               std::array<int, 2 * kWidth>& order) {
        const Ops::Float distance = Ops::max(Ops::load(along), Ops::broadcast(-kInfinity));
        alignas(32) float key[kWidth];
        Ops::store(key, distance);
        for (int slot = 0; slot < kWidth; ++slot) {
            const Ops::Float mine = Ops::broadcast(key[slot]);
            const unsigned before = Ops::bits(Ops::less(distance, mine)) |
                                    (Ops::bits(Ops::equal(distance, mine)) & ((1u << slot) - 1u));
            const unsigned missed = ((hit_children >> slot) & 1u) ^ 1u;
            order[static_cast<std::size_t>(std::popcount(before & hit_children)) + missed * kWidth] = slot;
        }
        return std::popcount(hit_children);
    }

    // A leaf's triangle blocks against each of `rays`, with bvh8's own block tests: where the leaf has a
    // header (has_leaf_boxes), each ray tests the blocks whose boxes it crosses, by test_children's
    // arithmetic.
    template <bool kCount>
    [[gnu::always_inline]] void test_leaf(ChildRef leaf, const std::array<int, 3>& side, RayBits rays,
                                          TraversalCounters& counts) {
        const LeafSpan span = leaf_span<kWidth>(leaf.child, leaf.prim_count);
        const bool has_boxes = has_leaf_boxes(leaf.child);
        Ops::Float near_bound[3], far_bound[3];
        if (has_boxes) load_bounds(leaf_boxes(blocks_[leaf_start(leaf.child)]), side, near_bound, far_bound);
        for (RayBits rest = rays; rest != 0; rest &= rest - 1) {
            const int k = std::countr_zero(rest);
            unsigned crossed = ~0u;
            if (has_boxes) {
                Ops::Float t0 = Ops::broadcast(tnear_[k]), t1 = Ops::broadcast(tlimit_[k]);
                clip_ray(k, near_bound, far_bound, t0, t1);
                crossed = Ops::bits(Ops::less_equal(t0, t1));
            }
            if constexpr (kCount) ++counts.nodes_visited;
            const auto& block_ray = block_rays_[static_cast<std::size_t>(k)];
            // Only the crossed blocks, by their bits: a ray crosses an unpredictable few of them, and a
            // branch on each block's bit was the streams' most mispredicted (docs/log/stream.md, "The
            // crossed blocks by their bits").
            const std::uint32_t blocks = span.end - span.first;
            for (unsigned left = crossed & ((1u << blocks) - 1u); left != 0; left &= left - 1) {
                const auto index = static_cast<std::uint32_t>(std::countr_zero(left));
                if constexpr (kCount) counts.prims_tested += block_primitives<kWidth>(leaf.prim_count, index);
                if constexpr (kAnyHit) {
                    if (occludes_block(geometry_, blocks_[span.first + index], *block_ray)) {
                        alive_ &= ~(RayBits{1} << k);
                        break;
                    }
                } else {
                    intersect_block(geometry_, blocks_[span.first + index], *block_ray, best_[k]);
                }
            }
            if (!kAnyHit && best_[k].hit()) tlimit_[k] = best_[k].t;
        }
    }

    // The planes of 8 boxes in a node's bounds layout that the stream's rays enter and leave by. Always
    // inlined: out of line, its planes came back through memory at every node.
    [[gnu::always_inline]] static void load_bounds(const float* lo_hi, const std::array<int, 3>& side,
                                                   Ops::Float (&near_bound)[3], Ops::Float (&far_bound)[3]) {
        for (int axis = 0; axis < 3; ++axis) {
            const int s = side[static_cast<std::size_t>(axis)];
            near_bound[axis] = Ops::load(lo_hi + (s * 3 + axis) * kWidth);
            far_bound[axis] = Ops::load(lo_hi + ((1 - s) * 3 + axis) * kWidth);
        }
    }

    // Ray k's interval [t0, t1] clipped by the 8 boxes' slabs: bvh8's box test (intersect_children).
    [[gnu::always_inline]] void clip_ray(int k, const Ops::Float (&near_bound)[3],
                                         const Ops::Float (&far_bound)[3], Ops::Float& t0,
                                         Ops::Float& t1) const {
        for (int axis = 0; axis < 3; ++axis)
            clip_slab<Ops, true>(near_bound[axis], far_bound[axis], Ops::broadcast(origin_[axis][k]),
                                 Ops::broadcast(inv_direction_[axis][k]), t0, t1);
    }

    const HugePageVector<Node>& nodes_;
    const HugePageVector<Block>& blocks_;
    const Geometry& geometry_;
    alignas(32) float origin_[3][kCapacity];
    alignas(32) float inv_direction_[3][kCapacity];
    alignas(32) float tnear_[kCapacity];
    alignas(32) float tlimit_[kCapacity];  // tfar, or the closest hit so far
    alignas(64) std::array<RayBits, kWidth> child_rays_;
    std::array<std::optional<PreparedRay<TriangleTestT>>, kCapacity> prepared_;
    std::array<std::optional<BlockRay<TriangleTestT, Bvh8Accel::kBlockLanes>>, kCapacity> block_rays_;
    // A plain array: std::array<Hit, N>'s constructor may be left out of line under a name the AVX2 baseline
    // shares (docs/isa.md, "Why the namespaces").
    Hit best_[kCapacity];
    RayBits alive_ = 0;               // occlusion: the rays not yet occluded; closest hits: all of them
    std::uint32_t index_[kCapacity];  // where each ray's answer goes
    int count_ = 0;
    WalkState walk_;  // a stream in flight's walk between its steps, and its stack
    Stack stack_;
    bool done_ = true;
};

// The batch's rays sorted into a stream per octant as they come, each stream traced when it is full and the
// others at the end, as Embree's stream call sorts its rays. Invalid rays miss; a ray that starts behind its
// origin (tnear < 0), which the stream's box test does not take, walks alone with bvh8's walk. With
// `in_flight` above 1 (a tree larger than the caches: bvh.interleaved_streams), up to that many full streams
// walk at once, a node of each in turn, so that the misses of one stream's next node overlap the others'
// work (docs/accel/stream.md, "Streams in flight").
template <class TriangleTestT, bool kAnyHit>
class RayStreams {
  public:
    using Answer = typename RayStream<TriangleTestT, kAnyHit>::Answer;

    RayStreams(const Bvh8Accel& bvh, const Geometry& geometry, int in_flight)
        : bvh_(bvh),
          geometry_(geometry),
          in_flight_(std::clamp(in_flight, 1, kStreamsInFlight)),
          first_(bvh, geometry) {}

    // Answers rays[i] in answers[i], now or by a later add or finish.
    template <bool kCount>
    void add(std::span<const Ray> rays, std::size_t i, std::span<Answer> answers, TraversalCounters& counts) {
        answers[i] = Answer{};
        const Ray& ray = rays[i];
        const int entry = stream_entry(ray);
        if (entry == kInvalid) return;
        if (entry == kBehind) {
            const PreparedRay<TriangleTestT> prepared(ray);
            if constexpr (kAnyHit) {
                Hit best;
                answers[i] = wide_walk::traverse<kWidth, true, kCount>(bvh_.nodes(), bvh_.blocks(), geometry_,
                                                                       prepared, best, counts)
                                 ? 1
                                 : 0;
            } else {
                wide_walk::traverse<kWidth, false, kCount>(bvh_.nodes(), bvh_.blocks(), geometry_, prepared,
                                                           answers[i], counts);
            }
            return;
        }
        const auto octant = static_cast<unsigned>(entry);
        int& count = count_[octant];
        waiting_[octant][static_cast<std::size_t>(count++)] = static_cast<std::uint32_t>(i);
        if (count == kCapacity) trace<kCount>(octant, rays, answers, counts);
    }

    // Traces the streams that are not full.
    template <bool kCount>
    void finish(std::span<const Ray> rays, std::span<Answer> answers, TraversalCounters& counts) {
        for (unsigned octant = 0; octant < 8; ++octant) {
            if (count_[octant] != 0) trace<kCount>(octant, rays, answers, counts);
        }
        while (running_ > 0)
            end_one<kCount>(answers, counts);
    }

  private:
    static constexpr int kCapacity = RayStream<TriangleTestT, kAnyHit>::kCapacity;

    // A stream that is full is traced at once, or, with streams in flight, started in a free slot (after
    // the running ones have stepped until one ended, when none is free).
    template <bool kCount>
    void trace(unsigned octant, std::span<const Ray> rays, std::span<Answer> answers,
               TraversalCounters& counts) {
        if (in_flight_ == 1) {
            first_.template trace<kCount>(rays, waiting_[octant].data(), count_[octant], octant, answers,
                                          counts);
            count_[octant] = 0;
            return;
        }
        if (running_ == in_flight_) end_one<kCount>(answers, counts);
        std::size_t slot = 0;
        while (busy_[slot])
            ++slot;
        if (slot > 0 && !others_[slot - 1]) others_[slot - 1].emplace(bvh_, geometry_);
        stream(slot).start(rays, waiting_[octant].data(), count_[octant], octant);
        busy_[slot] = true;
        ++running_;
        count_[octant] = 0;
    }

    // Steps the running streams in turn, a node or leaf each, until one ends, and writes its answers.
    template <bool kCount>
    void end_one(std::span<Answer> answers, TraversalCounters& counts) {
        while (true) {
            const auto slot = static_cast<std::size_t>(turn_);
            turn_ = turn_ + 1 == in_flight_ ? 0 : turn_ + 1;
            if (!busy_[slot] || stream(slot).template step<kCount>(counts)) continue;
            stream(slot).finish(answers);
            busy_[slot] = false;
            --running_;
            return;
        }
    }

    [[nodiscard]] RayStream<TriangleTestT, kAnyHit>& stream(std::size_t slot) {
        return slot == 0 ? first_ : *others_[slot - 1];
    }

    const Bvh8Accel& bvh_;
    const Geometry& geometry_;
    const int in_flight_;
    RayStream<TriangleTestT, kAnyHit> first_;
    // The other streams in flight, made at their first use.
    std::array<std::optional<RayStream<TriangleTestT, kAnyHit>>, kStreamsInFlight - 1> others_;
    std::array<bool, kStreamsInFlight> busy_{};
    int running_ = 0, turn_ = 0;
    std::array<std::array<std::uint32_t, kCapacity>, 8> waiting_;  // the rays of each octant's next stream
    std::array<int, 8> count_{};
};

}  // namespace
}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
