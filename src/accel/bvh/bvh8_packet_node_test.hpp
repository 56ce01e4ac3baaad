// The node test of bvh8_packet's kernel, kept apart from its traversal loop (bvh8_packet_kernel.cpp) as
// Embree keeps its node intersectors apart from its traversals: the whole packet, as intervals, against 8
// boxes at once (interval_cull.hpp's cull, on a node's children or here on a leaf block's triangles), and
// then the packet's own rays against one child, a group of rays per instruction. Private to the kernel's
// source (bvh8_packet_rays.hpp says why the anonymous namespace).
#pragma once

#include <bit>
#include <cstddef>

#include "accel/bvh/bvh8_packet_rays.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/interval_cull.hpp"
#include "accel/simd_float.hpp"
#include "core/isa_namespace.hpp"

#if defined(__AVX2__)
namespace lancer {
inline namespace LANCER_ISA_NAMESPACE {
namespace {

// The bounding boxes of a block's 8 triangles grown by the scene's geometric tolerance, for cull_boxes: the
// triangle tests report hits up to a rounding error outside their triangle, and the grown box still holds
// them (the argument for a leaf's box, which the build grows by the same tolerance;
// docs/numerical-contract.md, "Boxes"). `triangles`: the lanes that hold one (padding and spheres have NaN
// vertices, whose boxes cull_boxes would pass: its max and min drop NaN operands).
struct TriangleBoxes {
    Boxes bounds;
    unsigned triangles;
};
[[nodiscard]] TriangleBoxes triangle_boxes(const Block& block, float tolerance) {
    using Ops = simd::Avx2;
    const auto margin = Ops::broadcast(tolerance);
    TriangleBoxes boxes;
    for (int axis = 0; axis < 3; ++axis) {
        const auto v0 = Ops::load(block.vertex[0][axis]), v1 = Ops::load(block.vertex[1][axis]),
                   v2 = Ops::load(block.vertex[2][axis]);
        boxes.bounds[Node::kLo][axis] = Ops::sub(Ops::min(v0, Ops::min(v1, v2)), margin);
        boxes.bounds[Node::kHi][axis] = Ops::add(Ops::max(v0, Ops::max(v1, v2)), margin);
    }
    boxes.triangles = Ops::bits(Ops::equal(boxes.bounds[Node::kLo][0], boxes.bounds[Node::kLo][0]));
    return boxes;
}

// intersect_box on the packet's rays `rays` against child `slot` of `node`, a group of Ops::kWidth rays per
// instruction: the rays whose [tnear, tlimit] meets the child's box. Every ray's reciprocal direction is
// finite and of the packet's sign on each axis, so no plane distance is NaN and the near face is the same
// for all: the operations are those of bvh8's intersect_children, lane for lane.
template <class Ops>
[[nodiscard]] LaneMask box_groups(const PacketRays& packet, const PacketInterval& interval, const Node& node,
                                  int slot, LaneMask rays) {
    constexpr int lanes = Ops::kWidth;
    constexpr LaneMask kGroup = (LaneMask{1} << lanes) - 1;
    typename Ops::Float near_bound[3], far_bound[3];
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const int side = interval.near_side[axis];
        near_bound[axis] = Ops::broadcast(node.bounds[side][axis][slot]);
        far_bound[axis] = Ops::broadcast(node.bounds[1 - side][axis][slot]);
    }
    LaneMask result = 0;
    // The groups with rays alone: where triangles are small beside the packet (the dragon), most children
    // are met by one group's rays.
    for (LaneMask rest = rays; rest != 0;) {
        const int first = std::countr_zero(rest) & -lanes;
        const LaneMask group = (rest >> first) & kGroup;
        rest &= ~(kGroup << first);
        auto t0 = Ops::load(&packet.tnear[first]);
        auto t1 = Ops::load(&packet.tlimit[first]);
        for (std::size_t axis = 0; axis < 3; ++axis) {
            clip_slab<Ops>(near_bound[axis], far_bound[axis], Ops::load(&packet.origin[axis][first]),
                           Ops::load(&packet.inv_direction[axis][first]), t0, t1);
        }
        result |= (static_cast<LaneMask>(Ops::bits(Ops::less_equal(t0, t1))) & group) << first;
    }
    return result;
}

}  // namespace
}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
