// bvh8_packet's walk for closest hits of packets whose directions spread too far for the interval cull of its
// large packets (docs/accel/stream.md; any-hit rays go by the occlusion streams of bvh8_packet_stream.hpp):
// Ops::kWidth rays of any directions walk bvh8 together, every ray testing the node's
// 8 children in its own lane, while enough of them meet the same nodes; at a node that fewer rays reach, each
// goes on alone with bvh8's own single-ray walk from that node (bvh_wide_walk.hpp).
// This is the hybrid traversal of Benthin, Wald, Woop, Ernst & Mark, "Combining Single and Packet-Ray
// Tracing for Arbitrary Ray Distributions on the Intel MIC Architecture" (TVCG 2012), which Embree's 8- and
// 16-ray calls run. Each lane's box test is clip_slab's, the single-ray test's arithmetic, and every leaf is
// tested with bvh8's triangle blocks, so each ray gets bvh8's closest hit bit for bit (docs/accel/packets.md,
// "The numerical contract"). Included by the packet kernel's source alone (bvh8_packet_kernel.cpp).
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <optional>
#include <span>
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

template <class Ops, class TriangleTestT>
class HybridPacket {
  public:
    static constexpr int kLanes = Ops::kWidth;

    HybridPacket(const Bvh8Accel& bvh, const Geometry& geometry)
        : nodes_(bvh.nodes()), blocks_(bvh.blocks()), geometry_(geometry) {}

    // The fewest rays that still walk a node together: below it the single-ray walk is cheaper than a box
    // test of every lane (docs/accel/stream.md measures 2 to 12). The interval cull's packets hand their rays
    // over at the same count (Bvh8PacketTraversal::walk_alone).
    static constexpr int kHandover = 4;

    // Traces rays.size() <= kLanes rays of any directions; invalid rays miss. hits[i]: ray i's closest hit.
    // Rays whose origins' box is wider than `shared_width` walk alone from the root.
    template <bool kCount>
    void trace(std::span<const Ray> rays, std::span<Hit> hits, float shared_width,
               TraversalCounters& counts) {
        LaneBits valid = 0;
        bool forward = true;
        std::array<float, 3> lo{kInfinity, kInfinity, kInfinity}, hi{-kInfinity, -kInfinity, -kInfinity};
        for (int lane = 0; lane < kLanes; ++lane) {
            const auto index = static_cast<std::size_t>(lane);
            best_[index] = Hit{};
            // A lane without a valid ray enters every box at +inf and leaves at -inf: it never hits.
            tnear_[index] = kInfinity, tlimit_[index] = -kInfinity;
            for (int axis = 0; axis < 3; ++axis)
                origin_[axis][index] = 0.0f, inv_direction_[axis][index] = 1.0f;
            if (index >= rays.size() || !lane_is_valid(rays[index])) continue;
            const Ray& ray = rays[index];
            valid |= LaneBits{1} << lane;
            prepared_[index].emplace(ray);
            block_rays_[index].reset();
            const SlabRay slab(ray);
            for (int axis = 0; axis < 3; ++axis) {
                origin_[axis][index] = slab.origin[axis];
                inv_direction_[axis][index] = slab.inv_direction[axis];
                const auto a = static_cast<std::size_t>(axis);
                lo[a] = std::min(lo[a], slab.origin[axis]), hi[a] = std::max(hi[a], slab.origin[axis]);
            }
            tnear_[index] = ray.tnear, tlimit_[index] = ray.tfar;
            forward = forward && ray.tnear >= 0.0f;
        }
        const float width = std::max(hi[0] - lo[0], std::max(hi[1] - lo[1], hi[2] - lo[2]));
        if (valid != 0 && !nodes_.empty() && width > shared_width) {
            // Rays that start apart share no node below the root's: each walks alone.
            for (LaneBits rest = valid; rest != 0; rest &= rest - 1) {
                const auto lane = static_cast<std::size_t>(std::countr_zero(rest));
                wide_walk::traverse<kWidth, false, kCount>(nodes_, blocks_, geometry_, *prepared_[lane],
                                                           best_[lane], counts);
            }
        } else if (valid != 0 && !nodes_.empty()) {
            if (forward) {
                walk<kCount, true>(valid, counts);
            } else {
                walk<kCount, false>(valid, counts);
            }
        }
        for (std::size_t i = 0; i < rays.size(); ++i)
            hits[i] = best_[i];
    }

  private:
    using LaneBits = std::uint32_t;
    using Float = typename Ops::Float;
    using ChildRef = wide_walk::ChildRef;
    struct Entry {
        ChildRef ref;
        LaneBits lanes;
        float entry;  // the least entry distance of its lanes: a lane whose hit is nearer skips the child
    };

    template <bool kCount, bool kForward>
    void walk(LaneBits lanes, TraversalCounters& counts) {
        std::array<Entry, wide_walk::kStackSize<kWidth>> stack;
        int stack_size = 0;
        const Float tnear = Ops::load(tnear_.data());
        Float origin[3], inv_direction[3];
        // Each lane enters a box by the face its direction's sign picks, as WideRay does.
        typename Ops::Mask negative[3];
        for (int axis = 0; axis < 3; ++axis) {
            origin[axis] = Ops::load(origin_[axis]), inv_direction[axis] = Ops::load(inv_direction_[axis]);
            negative[axis] = Ops::mask_from_bits(Ops::sign_bits(inv_direction[axis]));
        }
        ChildRef current{0, 0};
        while (true) {
            if (current.prim_count > 0) {
                test_leaf<kCount>(current, lanes, counts);
            } else if (std::popcount(lanes) < kHandover) {
                // Too few rays left together: each finishes the subtree alone.
                for (LaneBits rest = lanes; rest != 0; rest &= rest - 1) {
                    const auto lane = static_cast<std::size_t>(std::countr_zero(rest));
                    wide_walk::traverse_from<kWidth, false, kCount, kForward>(
                        nodes_, blocks_, geometry_, *prepared_[lane], best_[lane], counts, current);
                    if (best_[lane].hit()) tlimit_[lane] = best_[lane].t;
                }
            } else {
                // INNER: each lane tests the 8 boxes; the children are visited by their least entry.
                if constexpr (kCount)
                    counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(lanes));
                const Node& node = nodes_[current.child];
                const Float tlimit = Ops::load(tlimit_.data());
                std::array<LaneBits, kWidth> child_lanes{};
                alignas(32) float entry[kWidth];
                unsigned hit_children = 0;
                for (int slot = 0; slot < kWidth && !node.is_empty(slot); ++slot) {
                    Float t0 = tnear, t1 = tlimit;
                    for (std::size_t axis = 0; axis < 3; ++axis) {
                        const Float lo = Ops::broadcast(node.bounds[Node::kLo][axis][slot]);
                        const Float hi = Ops::broadcast(node.bounds[Node::kHi][axis][slot]);
                        clip_slab<Ops, kForward>(Ops::select(negative[axis], hi, lo),
                                                 Ops::select(negative[axis], lo, hi), origin[axis],
                                                 inv_direction[axis], t0, t1);
                    }
                    const LaneBits hit = Ops::bits(Ops::less_equal(t0, t1)) & lanes;
                    if (hit == 0) continue;
                    child_lanes[static_cast<std::size_t>(slot)] = hit;
                    entry[slot] =
                        Ops::reduce_min(Ops::select(Ops::mask_from_bits(hit), t0, Ops::broadcast(kInfinity)));
                    hit_children |= 1u << slot;
                }
                if (hit_children != 0) {
                    std::array<int, kWidth> order;
                    const int count = order_by_entry<kWidth>(hit_children, entry, order);
                    for (int k = count - 1; k > 0; --k) {
                        const int slot = order[static_cast<std::size_t>(k)];
                        stack[static_cast<std::size_t>(stack_size++)] = {
                            {node.child[slot], node.prim_count[slot]},
                            child_lanes[static_cast<std::size_t>(slot)],
                            entry[slot]};
                    }
                    const int nearest = order[0];
                    current = {node.child[nearest], node.prim_count[nearest]};
                    lanes = child_lanes[static_cast<std::size_t>(nearest)];
                    continue;
                }
            }
            // POP the next child that some lane may still need.
            while (true) {
                if (stack_size == 0) return;
                const Entry& popped = stack[static_cast<std::size_t>(--stack_size)];
                const LaneBits need = popped.lanes & Ops::bits(Ops::less_equal(Ops::broadcast(popped.entry),
                                                                               Ops::load(tlimit_.data())));
                if (need == 0) continue;
                current = popped.ref, lanes = need;
                break;
            }
        }
    }

    // A leaf's triangle blocks against each of `lanes`, with bvh8's own block tests.
    template <bool kCount>
    void test_leaf(ChildRef leaf, LaneBits lanes, TraversalCounters& counts) {
        const std::uint32_t end = leaf.child + block_count(leaf.prim_count, Bvh8Accel::kBlockLanes);
        for (LaneBits rest = lanes; rest != 0; rest &= rest - 1) {
            const auto lane = static_cast<std::size_t>(std::countr_zero(rest));
            if constexpr (kCount) ++counts.nodes_visited, counts.prims_tested += leaf.prim_count;
            // Made at the lane's first leaf and kept for the others: most rays of a packet reach several.
            if (!block_rays_[lane]) block_rays_[lane].emplace(*prepared_[lane], geometry_);
            const BlockRay<TriangleTestT, Bvh8Accel::kBlockLanes>& block_ray = *block_rays_[lane];
            for (std::uint32_t b = leaf.child; b < end; ++b)
                intersect_block(geometry_, blocks_[b], block_ray, best_[lane]);
            if (best_[lane].hit()) tlimit_[lane] = best_[lane].t;
        }
    }

    const std::vector<Node>& nodes_;
    const std::vector<Block>& blocks_;
    const Geometry& geometry_;
    alignas(64) float origin_[3][kLanes];
    alignas(64) float inv_direction_[3][kLanes];
    alignas(64) std::array<float, kLanes> tnear_;
    alignas(64) std::array<float, kLanes> tlimit_;  // the closest hit so far, or tfar
    std::array<std::optional<PreparedRay<TriangleTestT>>, kLanes> prepared_;
    std::array<std::optional<BlockRay<TriangleTestT, Bvh8Accel::kBlockLanes>>, kLanes> block_rays_;
    std::array<Hit, kLanes> best_;
};

}  // namespace
}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
