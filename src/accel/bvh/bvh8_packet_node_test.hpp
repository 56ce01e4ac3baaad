// The node test of bvh8_packet's kernel, kept apart from its traversal loop (bvh8_packet_kernel.cpp) as
// Embree keeps its node intersectors apart from its traversals: the whole packet, as intervals, against 8
// boxes at once and then the packet's own rays against one child (interval_cull.hpp, which the instances'
// top level shares), on a node's children or, here, on a leaf block's triangles' boxes. Private to the
// kernel's source (bvh8_packet_rays.hpp says why the anonymous namespace).
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

}  // namespace
}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
