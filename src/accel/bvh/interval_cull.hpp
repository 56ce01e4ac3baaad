// A packet of rays against a wide node: the interval cull of the whole packet against 8 boxes at once, then
// each ray's own slab test against one child. bvh8_packet's node and leaf culls (bvh8_packet_kernel.cpp,
// bvh8_packet_leaf_tests.hpp) and the instances' top level (accel/instance/top_level_walk.hpp) share them.
// In the instruction set's namespace (core/isa_namespace.hpp): the packet kernel's source is compiled once
// per instruction set.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>

#include "accel/bvh/bvh_wide.hpp"
#include "accel/simd_float.hpp"
#include "core/intersect.hpp"
#include "core/isa_namespace.hpp"

#if defined(__AVX2__)
namespace lancer {
inline namespace LANCER_ISA_NAMESPACE {

// The packet's rays as intervals, for the conservative child test: every ray's origin lies in
// [origin_lo, origin_hi] and its reciprocal direction in [inv_lo, inv_hi], one sign per axis.
struct PacketInterval {
    std::array<float, 3> entry_origin, exit_origin;  // the corner of the origin box each plane distance takes
    std::array<float, 3> inv_lo, inv_hi;
    std::array<int, 3> near_side;  // WideBvhNode::kLo or kHi: the face a ray enters by on each axis
    float tnear_min;

    // The intervals of one axis, its near_side set: the entry is smallest from the origin nearest the far
    // side, the exit largest from the other.
    void set_axis(std::size_t axis, float origin_lo, float origin_hi, float reciprocal_lo,
                  float reciprocal_hi) {
        const bool negative = near_side[axis] == WideBvhNode<8>::kHi;
        entry_origin[axis] = negative ? origin_lo : origin_hi;
        exit_origin[axis] = negative ? origin_hi : origin_lo;
        inv_lo[axis] = reciprocal_lo, inv_hi[axis] = reciprocal_hi;
    }
};

// is_valid (lancer/ray.hpp) lane by lane on a group of rays' transposed fields (ox oy oz dx dy dz tnear tfar,
// Ops::load_fields8): finite origin, direction and tnear, a nonzero direction component, tfar not NaN and
// tnear <= tfar. NaN compares false, so `|x| < inf` is isfinite and `tfar == tfar` is !isnan.
template <class Ops>
[[nodiscard]] inline typename Ops::Mask valid_ray_lanes(const typename Ops::Float (&fields)[8]) {
    const auto infinity = Ops::broadcast(kInfinity), zero = Ops::broadcast(0.0f);
    const auto tnear = fields[6], tfar = fields[7];
    auto valid = Ops::mask_and(Ops::less(Ops::abs(tnear), infinity),
                               Ops::mask_and(Ops::equal(tfar, tfar), Ops::less_equal(tnear, tfar)));
    auto nonzero = Ops::greater(Ops::abs(fields[3]), zero);
    for (int axis = 0; axis < 3; ++axis) {
        valid = Ops::mask_and(valid, Ops::mask_and(Ops::less(Ops::abs(fields[axis]), infinity),
                                                   Ops::less(Ops::abs(fields[3 + axis]), infinity)));
        if (axis > 0) nonzero = Ops::mask_or(nonzero, Ops::greater(Ops::abs(fields[3 + axis]), zero));
    }
    return Ops::mask_and(valid, nonzero);
}

using Boxes = simd::Avx2::Float[2][3];  // [kLo | kHi][axis]: 8 boxes, one per lane

// The boxes (8, one per lane) that some ray of the packet may hit within [tnear_min, tlimit_max]: bit i set,
// with entry[i] a lower bound of where any ray enters box i. Interval arithmetic on the slab test (Overbeck
// et al. 2008): every plane distance fl(fl(b - o) * r) is monotone in o and in r, so the corner
// of the intervals chosen by the signs of b - o and r bounds it over the packet, in the same fp32 operations.
// The exit's widening (widened_slab_exit) is monotone too. A ray whose own test (clip_slab, bvh_wide.hpp)
// passes thus always finds its box's bit set. Empty slots (lo = +inf, hi = -inf) enter at +inf and leave at
// -inf.
[[nodiscard]] inline unsigned cull_boxes(const Boxes& bounds, const PacketInterval& packet, float tlimit_max,
                                         float (&entry)[8]) {
    using Ops = simd::Avx2;
    auto t0 = Ops::broadcast(packet.tnear_min), t1 = Ops::broadcast(tlimit_max);
    const auto zero = Ops::broadcast(0.0f);
    const auto grow = Ops::broadcast(kSlabExitGrow), shrink = Ops::broadcast(kSlabExitShrink);
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const int side = packet.near_side[axis];
        const auto inv_lo = Ops::broadcast(packet.inv_lo[axis]), inv_hi = Ops::broadcast(packet.inv_hi[axis]);
        // Smallest entry: the near plane's distance from the farthest origin, times the reciprocal that
        // makes the product smallest (the largest magnitude for a negative distance).
        const auto near_distance = Ops::sub(bounds[side][axis], Ops::broadcast(packet.entry_origin[axis]));
        const auto near_plane =
            Ops::mul(near_distance, Ops::select_if_greater(zero, near_distance, inv_hi, inv_lo));
        // Largest exit, widened.
        const auto far_distance = Ops::sub(bounds[1 - side][axis], Ops::broadcast(packet.exit_origin[axis]));
        const auto far_unwidened =
            Ops::mul(far_distance, Ops::select_if_greater(zero, far_distance, inv_lo, inv_hi));
        const auto far_plane =
            Ops::mul(far_unwidened, Ops::select_if_greater(far_unwidened, zero, grow, shrink));
        t0 = Ops::max(near_plane, t0);
        t1 = Ops::min(far_plane, t1);
    }
    Ops::store(entry, t0);
    return Ops::bits(Ops::less_equal(t0, t1));
}

// cull_boxes on the 8 children of a wide node.
[[nodiscard]] inline unsigned cull_children(const WideBvhNode<8>& node, const PacketInterval& packet,
                                            float tlimit_max, float (&entry)[8]) {
    using Ops = simd::Avx2;
    Boxes bounds;
    for (int side = 0; side < 2; ++side) {
        for (int axis = 0; axis < 3; ++axis)
            bounds[side][axis] = Ops::load(node.bounds[side][axis]);
    }
    return cull_boxes(bounds, packet, tlimit_max, entry);
}

// The packet's `rays` (bit i: ray i) whose own slab test meets child `slot` of `node` within [tnear,
// tlimit], a group of Ops::kWidth rays per instruction. `packet` holds the rays one array per coordinate:
// origin[3][], inv_direction[3][], tnear[] and tlimit[]. Every ray's reciprocal direction is finite and has
// the packet's sign on each axis (`near_side`), so no plane distance is NaN and the near face is the same
// for all: the operations are those of the single-ray walk's intersect_children (clip_slab), lane for lane.
template <class Ops, class PacketArrays>
[[nodiscard]] inline std::uint64_t box_groups(const PacketArrays& packet, const std::array<int, 3>& near_side,
                                              const WideBvhNode<8>& node, int slot, std::uint64_t rays) {
    constexpr int lanes = Ops::kWidth;
    constexpr std::uint64_t kGroup = (std::uint64_t{1} << lanes) - 1;
    typename Ops::Float near_bound[3], far_bound[3];
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const int side = near_side[axis];
        near_bound[axis] = Ops::broadcast(node.bounds[side][axis][slot]);
        far_bound[axis] = Ops::broadcast(node.bounds[1 - side][axis][slot]);
    }
    std::uint64_t result = 0;
    // The groups with rays alone: where triangles are small beside the packet (the dragon), most children
    // are met by one group's rays.
    for (std::uint64_t rest = rays; rest != 0;) {
        const int first = std::countr_zero(rest) & -lanes;
        const std::uint64_t group = (rest >> first) & kGroup;
        rest &= ~(kGroup << first);
        auto t0 = Ops::load(&packet.tnear[first]);
        auto t1 = Ops::load(&packet.tlimit[first]);
        for (std::size_t axis = 0; axis < 3; ++axis) {
            clip_slab<Ops>(near_bound[axis], far_bound[axis], Ops::load(&packet.origin[axis][first]),
                           Ops::load(&packet.inv_direction[axis][first]), t0, t1);
        }
        result |= (static_cast<std::uint64_t>(Ops::bits(Ops::less_equal(t0, t1))) & group) << first;
    }
    return result;
}

}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
