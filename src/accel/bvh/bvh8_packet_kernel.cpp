// The kernel of bvh8_packet (bvh8_packet.hpp): its traversal loop and its entry points. The packet
// (bvh8_packet_rays.hpp), the node test (bvh8_packet_node_test.hpp), the leaf tests
// (bvh8_packet_leaf_tests.hpp) and the ray streams of incoherent rays (bvh8_packet_stream.hpp) are in
// headers of their own, included here alone. This one source is compiled
// once per instruction set, by lancer_core for AVX2 (8 rays per instruction) and by lancer_kernels_avx512 for
// AVX-512 (16), each into its own namespace (core/isa_namespace.hpp), and Bvh8PacketAccel picks one when it
// is built (lancer/isa.hpp).
#include "accel/bvh/bvh8_packet_kernel.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <span>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/bvh8_packet_leaf_tests.hpp"
#include "accel/bvh/bvh8_packet_node_test.hpp"
#include "accel/bvh/bvh8_packet_rays.hpp"
#include "accel/bvh/bvh8_packet_stream.hpp"
#include "accel/bvh/bvh_wide_walk.hpp"
#include "accel/packet_batch.hpp"
#include "accel/simd_float.hpp"

#if defined(__AVX2__)
namespace lancer {
inline namespace LANCER_ISA_NAMESPACE {
namespace {

// A child the traversal will visit: `slot` of `parent`, with the rays that met the parent and a lower bound
// of where any of them enters the child.
struct StackEntry {
    const Node* parent;
    int slot;
    float entry;
    LaneMask rays;
};
constexpr int kStackSize = kWidth * BvhAccel::kMaxDepth + 1;

// One packet: loaded (LoadedPacket), then traced, its nodes culled and tested here and its leaves tested by
// PacketLeafTests. Ops: the lane width of the box and triangle tests.
template <class Ops, class TriangleTestT>
class Bvh8PacketTraversal : public PacketLeafTests<Ops, TriangleTestT> {
    using Packet = LoadedPacket<Ops, TriangleTestT>;
    using Packet::alive_, Packet::interval_, Packet::packet_, Packet::tlimit_max_, Packet::valid_;
    using Packet::max_tlimit;

  public:
    Bvh8PacketTraversal(const Bvh8Accel& bvh, const Geometry& geometry, RaySource source)
        : PacketLeafTests<Ops, TriangleTestT>(bvh, geometry, source), nodes_(bvh.nodes()) {}

    // Front to back: the children that survive the cull are ordered by their entry bound and pushed, the
    // nearest on top; a popped child is tested against its rays, and skipped when it is entered beyond
    // every ray's closest hit. kAnyHit: a ray leaves the packet at its first hit, and the children go in
    // slot order. `answers` starts as misses; on return answers[i] is ray i's closest hit (Hit) or
    // occlusion (uint8).
    template <bool kAnyHit, bool kCount, class Answer>
    void trace(std::span<Answer> answers, TraversalCounters& counts) {
        alive_ = valid_;
        if (nodes_.empty() || alive_ == 0) return;
        tlimit_max_ = max_tlimit();
        std::array<StackEntry, kStackSize> stack;
        int stack_size = 0;
        const Node* node = &nodes_[0];
        LaneMask rays = alive_;
        while (true) {
            // INNER: cull the children and push the survivors, the first to visit on top.
            if constexpr (kCount) counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(rays));
            alignas(32) float entry[kWidth];
            std::array<int, kWidth> order;
            const unsigned hit_children = cull_children(*node, interval_, tlimit_max_, entry);
            // Any hit ends a ray, so for occlusion the order only decides where the first is found: slot
            // order, without the sort's branches, as bvh8's any-hit walk (docs/accel/packets.md, "Occlusion
            // packets in slot order").
            const int count = kAnyHit ? order_by_slot(hit_children, order)
                                      : order_by_entry<kWidth>(hit_children, entry, order);
            for (int k = count - 1; k >= 0; --k)
                stack[stack_size++] = {node, order[k], entry[order[k]], rays};
            // Every pushed child's lines are requested now, the first to visit first: on a tree larger than
            // the caches the pops' misses then overlap instead of following one another
            // (docs/accel/packets.md, "Large meshes: prefetching the pushed children").
            for (int k = 0; k < count; ++k) {
                const int slot = order[k];
                wide_walk::prefetch_child<kWidth>(nodes_, blocks_, node->child[slot], node->prim_count[slot]);
            }
            // POP until an inner child with rays in it, testing the leaves on the way.
            while (true) {
                if (stack_size == 0) return;
                const StackEntry popped = stack[--stack_size];
                if (popped.entry > tlimit_max_) continue;
                rays = box_groups<Ops>(packet_, interval_.near_side, *popped.parent, popped.slot,
                                       popped.rays & alive_);
                if (rays == 0) continue;
                const std::uint32_t prim_count = popped.parent->prim_count[popped.slot];
                const std::uint32_t child = popped.parent->child[popped.slot];
                if (prim_count == 0) {
                    if (std::popcount(rays) < kHandover) {
                        walk_alone<kAnyHit, kCount>(child, rays, answers, counts);
                        if constexpr (kAnyHit) {
                            if (alive_ == 0) return;
                        } else {
                            tlimit_max_ = max_tlimit();
                        }
                        continue;
                    }
                    node = &nodes_[child];
                    break;
                }
                if constexpr (kCount) {
                    counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(rays));
                    counts.prims_tested += static_cast<std::uint64_t>(prim_count) *
                                           static_cast<std::uint64_t>(std::popcount(rays));
                }
                if (this->template test_leaf<kAnyHit>(child, prim_count, rays, answers)) {
                    if constexpr (kAnyHit) {
                        if (alive_ == 0) return;
                    } else {
                        tlimit_max_ = max_tlimit();
                    }
                }
            }
        }
    }

  private:
    using PacketLeafTests<Ops, TriangleTestT>::blocks_, PacketLeafTests<Ops, TriangleTestT>::geometry_;

    // The fewest rays that still walk a node together: below it the single-ray walk is cheaper than the
    // packet's tests (docs/accel/packets.md, "Few rays at a node"; 2 to 12 were measured).
    static constexpr int kHandover = 4;

    // The `rays` that reach inner node `node` when too few of them are left for the packet's tests to pay
    // (where triangles are small beside the packet's footprint, as on the dragon): each finishes that
    // subtree alone with bvh8's walk from its closest hit so far, the hand-over of Benthin et al.'s hybrid
    // traversal (TVCG 2012; docs/accel/packets.md).
    template <bool kAnyHit, bool kCount, class Answer>
    void walk_alone(std::uint32_t node, LaneMask rays, std::span<Answer> answers, TraversalCounters& counts) {
        for (LaneMask rest = rays; rest != 0; rest &= rest - 1) {
            const int i = std::countr_zero(rest);
            const PreparedRay<TriangleTestT> prepared(
                Ray{{packet_.origin[0][i], packet_.origin[1][i], packet_.origin[2][i]},
                    {packet_.direction[0][i], packet_.direction[1][i], packet_.direction[2][i]},
                    packet_.tnear[i],
                    packet_.tfar[i]});
            Hit best = packet_.prim[i] == kNoHit
                           ? Hit{}
                           : Hit{packet_.tlimit[i], packet_.prim[i], packet_.u[i], packet_.v[i]};
            const bool hit = wide_walk::traverse<kWidth, kAnyHit, kCount>(nodes_, blocks_, geometry_,
                                                                          prepared, best, counts, {node, 0});
            if constexpr (kAnyHit) {
                if (hit) {
                    answers[static_cast<std::size_t>(i)] = 1;
                    alive_ &= ~(LaneMask{1} << i);
                }
            } else if (best.hit()) {
                packet_.tlimit[i] = best.t, packet_.prim[i] = best.prim;
                packet_.u[i] = best.u, packet_.v[i] = best.v;
            }
        }
    }

    const HugePageVector<Node>& nodes_;
};

// Cuts the batch into packets of consecutive rays. A packet whose rays go together (the same direction signs,
// finite reciprocals, directions close together, origins close together beside the tree's leaves) walks with
// the interval cull; the rays of any other join the stream of their direction octant
// (bvh8_packet_stream.hpp), which takes any rays. Answer: Hit (closest hit) or std::uint8_t (occlusion,
// kAnyHit). docs/accel/stream.md has the measurements behind the spread and the streams.
template <class Ops, bool kAnyHit, class Answer>
void trace_batch(const Bvh8PacketTarget& target, std::span<const Ray> rays, std::span<Answer> answers,
                 TraversalCounters* counters) {
    // The interval cull takes a packet whose directions agree to half their largest component and whose
    // origins lie within 4 mean leaf diagonals: beyond, its rays share few leaves (docs/accel/stream.md).
    constexpr float kAgreeingSpread = 0.5f;
    constexpr float kCoherentLeaves = 4.0f;
    const Bvh8Accel& bvh = target.bvh;
    const Geometry& geometry = target.geometry;
    constexpr auto kPacketRays = static_cast<std::size_t>(kPacketSize);
    dispatch_policies(target.test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        Bvh8PacketTraversal<Ops, TriangleTestT> tracer(bvh, geometry, RaySource::batch);
        RayStreams<TriangleTestT, kAnyHit> streams(bvh, geometry, target.streams_in_flight);
        for (std::size_t first = 0; first < rays.size(); first += kPacketRays) {
            const std::size_t count = std::min(kPacketRays, rays.size() - first);
            const std::span<const Ray> packet_rays = rays.subspan(first, count);
            const std::span<Answer> packet_answers = answers.subspan(first, count);
            if constexpr (kCount) counts.rays += count;
            if (tracer.load(packet_rays) && tracer.directions_agree(kAgreeingSpread) &&
                tracer.origin_width() <= kCoherentLeaves * target.coherent_width) {
                if constexpr (kAnyHit) {
                    std::fill(packet_answers.begin(), packet_answers.end(), Answer{});
                    tracer.template trace<true, kCount>(packet_answers, counts);
                } else {
                    tracer.template trace<false, kCount>(packet_answers, counts);
                    tracer.store_hits(packet_answers);
                }
                continue;
            }
            for (std::size_t i = first; i < first + count; ++i)
                streams.template add<kCount>(rays, i, answers, counts);
        }
        streams.template finish<kCount>(rays, answers, counts);
        if constexpr (kCount) *counters += counts;
    });
}

// One packet in the caller's SoA layout, traced in place, or as a batch (trace_batch) when its rays cannot go
// together.
template <class Ops>
void trace_soa_packet(const Bvh8PacketTarget& target, const RayPacket& rays, HitPacket& hits,
                      TraversalCounters* counters) {
    dispatch_policies(target.test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        Bvh8PacketTraversal<Ops, TriangleTestT> tracer(target.bvh, target.geometry, RaySource::camera);
        if (tracer.load(rays)) {
            tracer.template trace<false, kCount>(std::span<Hit>(), counts);
            tracer.store_hits(hits);
            if constexpr (kCount) {
                counts.rays += static_cast<std::uint64_t>(rays.size);
                *counters += counts;
            }
            return;
        }
        trace_packet_as_batch(rays, hits, [&](std::span<const Ray> batch, std::span<Hit> batch_hits) {
            trace_batch<Ops, false>(target, batch, batch_hits, counters);
        });
    });
}

#if defined(LANCER_KERNEL_AVX512)
using KernelOps = simd::Avx512;
#else
using KernelOps = simd::Avx2;
#endif

void intersect(const Bvh8PacketTarget& target, std::span<const Ray> rays, std::span<Hit> hits,
               TraversalCounters* counters) {
    trace_batch<KernelOps, false>(target, rays, hits, counters);
}

void occluded(const Bvh8PacketTarget& target, std::span<const Ray> rays, std::span<std::uint8_t> occluded,
              TraversalCounters* counters) {
    trace_batch<KernelOps, true>(target, rays, occluded, counters);
}

void intersect_packet(const Bvh8PacketTarget& target, const RayPacket& rays, HitPacket& hits,
                      TraversalCounters* counters) {
    trace_soa_packet<KernelOps>(target, rays, hits, counters);
}

}  // namespace

const Bvh8PacketKernels& bvh8_packet_kernels() {
    static constexpr Bvh8PacketKernels kernels = {KernelOps::kWidth, intersect, occluded, intersect_packet};
    return kernels;
}

}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
