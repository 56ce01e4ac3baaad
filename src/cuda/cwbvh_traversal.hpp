// The per-ray traversal of the compressed wide BVH (cwbvh_layout.hpp) after Ylitie, Karras & Laine 2017
// (their traversal algorithm): a node group (a node's inner children hit, still to visit) and a triangle
// group (its leaves' triangles hit) per node, the groups left behind on a small per-thread stack, the inner
// children visited in octant order. For the device and, in tests/cuda, the host. Two deviations keep the
// CPU's arithmetic, so that the hits are bvh8's bit for bit: each child box is decoded to floats and tested
// with the CPU's robust slab test (intersect_box), not in the paper's pre-transformed ray frame, and
// triangles are tested one at a time by core/intersect.hpp's tests. docs/cuda.md, "The compressed wide
// BVH".
#pragma once

#include <bit>

#include "cuda/bvh_traversal.hpp"
#include "cuda/cwbvh_layout.hpp"
#include "cuda/triangle.hpp"

namespace lancer::gpu {

LANCER_HOST_DEVICE inline int highest_bit(std::uint32_t bits) {
#if defined(__CUDA_ARCH__)
    return 31 - __clz(static_cast<int>(bits));
#else
    return 31 - std::countl_zero(bits);
#endif
}
LANCER_HOST_DEVICE inline int lowest_bit(std::uint32_t bits) {
#if defined(__CUDA_ARCH__)
    return __ffs(static_cast<int>(bits)) - 1;
#else
    return std::countr_zero(bits);
#endif
}
LANCER_HOST_DEVICE inline std::uint32_t bit_count(std::uint32_t bits) {
#if defined(__CUDA_ARCH__)
    return static_cast<std::uint32_t>(__popc(bits));
#else
    return static_cast<std::uint32_t>(std::popcount(bits));
#endif
}

// A node's inner children hit and not yet visited: bit 24 + (slot ^ swizzle) for each (the octant order,
// highest first), and the node's inner mask in bits 0-7, which numbers an inner child among its siblings.
struct NodeGroup {
    std::uint32_t child_base = 0;
    std::uint32_t hits = 0;

    static constexpr std::uint32_t kChildBitsFrom = 24;
    [[nodiscard]] LANCER_HOST_DEVICE bool has_children() const { return hits >> kChildBitsFrom != 0; }
};

// The root as the only child of a group with an empty inner mask: child_base 0 plus no siblings before it.
inline constexpr NodeGroup kRootGroup = {0, 1u << 31};

// The groups left behind, in local memory on the device: one per level at most (kCwbvhStackSize).
struct CwbvhStack {
    NodeGroup entries[kCwbvhStackSize];
    int size = 0;

    LANCER_HOST_DEVICE void push(const NodeGroup& group) { entries[size++] = group; }
    LANCER_HOST_DEVICE NodeGroup pop() { return entries[--size]; }
    [[nodiscard]] LANCER_HOST_DEVICE bool empty() const { return size == 0; }
};

// The ray's octant (bit 2: x < 0, bit 1: y, bit 0: z) flipped: slot ^ swizzle is highest for the slot on
// the near side of every axis (the builder's slot s lies on the + side of axis a when bit 2 - a is set).
LANCER_HOST_DEVICE inline std::uint32_t octant_swizzle(const Vec3f& direction) {
    const std::uint32_t octant =
        (direction.x < 0.0f ? 4u : 0u) | (direction.y < 0.0f ? 2u : 0u) | (direction.z < 0.0f ? 1u : 0u);
    return octant ^ 7u;
}

// kAnyHit false: the closest hit (ties to the smaller primitive index, as every CPU structure). kAnyHit true:
// the first hit found within [tnear, tfar], not necessarily the closest. A miss for an invalid ray or an
// empty scene. Steps counts nodes fetched and triangle groups tested.
template <bool kAnyHit, class TriangleTestT, class Steps = NoSteps>
LANCER_HOST_DEVICE Hit trace_cwbvh(const CwbvhView& bvh, const Ray& ray, Steps&& steps = {}) {
    Hit best;
    if (!is_valid(ray) || bvh.node_count == 0) return best;
    const typename TriangleTestT::RayData triangle_ray(ray);
    const SlabRay slab(ray);
    const std::uint32_t swizzle = octant_swizzle(ray.direction);
    CwbvhStack stack;
    NodeGroup group = kRootGroup;
    while (true) {
        // NODE: the group's next child in octant order; its siblings wait on the stack.
        const int bit = highest_bit(group.hits);
        group.hits &= ~(1u << bit);
        const auto slot =
            static_cast<std::uint32_t>(bit - static_cast<int>(NodeGroup::kChildBitsFrom)) ^ swizzle;
        const std::uint32_t siblings_before = group.hits & 0xFFu & ((1u << slot) - 1u);
        const CwbvhNode node = read_only_record(bvh.nodes + group.child_base + bit_count(siblings_before));
        if (group.has_children()) stack.push(group);
        steps.step();

        // CHILDREN: each box decoded and tested by the slab test; inner children join the node's group,
        // leaves' triangles its triangle group. The best hit's t is widened as the slab exits are: a box is
        // tested when its node is fetched, not when bvh8 would pop it, and a hit on a box's corner can lie a
        // rounding below the box's entry distance, which would drop a tie of smaller index there
        // (make_unsplittable_scene in tests/cuda/cwbvh_port_test.cpp).
        const float limit = best.prim >= 0 ? widened_slab_exit(best.t) : ray.tfar;
        const float scale[3] = {quantization_scale(node.exponent[0]), quantization_scale(node.exponent[1]),
                                quantization_scale(node.exponent[2])};
        group = {node.child_base, node.inner_mask};
        std::uint32_t triangle_hits = 0;
        for (int s = 0; s < kCwbvhWidth; ++s) {
            if (is_empty_slot(node, s)) continue;
            float entry, exit;
            if (!intersect_box(slab, decoded_child_box(node, scale, s), ray.tnear, limit, entry, exit))
                continue;
            if (((node.inner_mask >> s) & 1u) != 0)
                group.hits |= 1u << (NodeGroup::kChildBitsFrom + (static_cast<std::uint32_t>(s) ^ swizzle));
            else
                triangle_hits |= leaf_triangle_bits(node.meta[s]);
        }

        // TRIANGLES: before the node's inner children, so that a hit here narrows their boxes' test.
        if (triangle_hits != 0) steps.step();
        for (; triangle_hits != 0; triangle_hits &= triangle_hits - 1u) {
            const TriangleRef* record = bvh.triangles + node.triangle_base + lowest_bit(triangle_hits);
            if (intersect_record<TriangleTestT>(record, triangle_ray, ray, best) && kAnyHit) return best;
        }

        // POP: the last group left behind once this node has no inner child hit.
        if (!group.has_children()) {
            if (stack.empty()) break;
            group = stack.pop();
        }
    }
    return best;
}

}  // namespace lancer::gpu
