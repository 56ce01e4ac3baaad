// 4- and 8-wide bounding volume hierarchies collapsed from the binary SAH BVH (Dammertz, Hanika & Keller,
// "Shallow Bounding Volume Hierarchies for Fast SIMD Ray Tracing of Incoherent Rays", EGSR 2008; Wald,
// Benthin & Boulos, "Getting Rid of Packets", RT 2008), traversed one ray at a time with all W child boxes
// tested at once in SIMD. docs/accel/bvh_wide.md has the design note.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/triangle_block.hpp"
#include "accel/simd_float.hpp"
#include "core/intersect.hpp"

namespace lancer {

// One wide node, structure of arrays so that one load brings a coordinate of all W children. Width 4:
// 96 bytes of boxes + 16 + 16 = 128 bytes (two cache lines); width 8: 192 + 32 + 32 = 256 bytes (four).
// An empty slot has the inverted box lo = +inf, hi = -inf, which the sign-selected slab test below never
// hits.
template <int W>
struct alignas(32) WideBvhNode {
    static constexpr int kLo = 0, kHi = 1;
    // 24 W bytes: [lo | hi][axis][child].
    float bounds[2][3][W];
    // 4 W bytes: an inner child's node index; a leaf child's first triangle block, or its header's with
    // kLeafHeaderBit set (below).
    std::uint32_t child[W] = {};
    // 4 W bytes: the primitives of a leaf child (in block_count(prim_count, kBlockLanes) blocks); 0 for an
    // inner child or an empty slot.
    std::uint32_t prim_count[W] = {};

    WideBvhNode() {
        for (int axis = 0; axis < 3; ++axis) {
            for (int slot = 0; slot < W; ++slot)
                bounds[kLo][axis][slot] = kInfinity, bounds[kHi][axis][slot] = -kInfinity;
        }
    }
    [[nodiscard]] bool is_empty(int slot) const { return bounds[kLo][0][slot] > bounds[kHi][0][slot]; }
    [[nodiscard]] Box3f child_bounds(int slot) const {
        return {{bounds[kLo][0][slot], bounds[kLo][1][slot], bounds[kLo][2][slot]},
                {bounds[kHi][0][slot], bounds[kHi][1][slot], bounds[kHi][2][slot]}};
    }
};
static_assert(sizeof(WideBvhNode<4>) == 128 && alignof(WideBvhNode<4>) == 32);
static_assert(sizeof(WideBvhNode<8>) == 256 && alignof(WideBvhNode<8>) == 32);

// bvh8's leaves of more than one block (the merged leaves of bvh.wide_leaf_size) may start with a header
// (bvh.leaf_boxes): one more block, in front of the leaf's triangle blocks, that holds the box of each of
// them, grown by the scene's geometric tolerance as the nodes' boxes are, in the layout of a node's bounds
// ([lo | hi][axis][block] in its vertex[0] and vertex[1]; unused lanes inverted, prim[] all kNoPrimitive).
// bvh8_packet's ray streams test the boxes of every block of the leaf for each ray with one node test, and
// then the triangles of the blocks the ray crosses only (docs/accel/bvh_wide.md, "Block boxes in merged
// leaves"). The leaf's slot marks a header by kLeafHeaderBit in its child index, so that the blocks'
// addresses are known without a load. bvh4's blocks of 4 have no room for 8 boxes: its leaves have no
// header.
template <int W>
inline constexpr bool kLeafBoxes = W == 8;
inline constexpr std::uint32_t kLeafHeaderBit = std::uint32_t{1} << 31;

[[nodiscard]] constexpr bool has_leaf_boxes(std::uint32_t child) {
    return (child & kLeafHeaderBit) != 0;
}

// A leaf child's triangle blocks in the block array, [first, end): from its first block (the node's child
// index), or after its header.
struct LeafSpan {
    std::uint32_t first = 0, end = 0;
};
template <int W>
[[nodiscard]] constexpr LeafSpan leaf_span(std::uint32_t child, std::uint32_t prim_count) {
    const std::uint32_t first = (child & ~kLeafHeaderBit) + (has_leaf_boxes(child) ? 1 : 0);
    return {first, first + block_count(prim_count, W)};
}
// The leaf's header, or its first block where it has none.
[[nodiscard]] constexpr std::uint32_t leaf_start(std::uint32_t child) {
    return child & ~kLeafHeaderBit;
}
// The primitives of the leaf's block `index` (from 0), for the counters.
template <int W>
[[nodiscard]] constexpr std::uint32_t block_primitives(std::uint32_t prim_count, std::uint32_t index) {
    return std::min<std::uint32_t>(W, prim_count - index * W);
}
// Writes `header`: the boxes of the leaf's blocks [blocks, blocks + count), count <= 8, from their
// primitives' boxes, grown by `margin`. The build and the refit both write it, so a refit to the built
// geometry restores its bytes.
void write_leaf_boxes(const Geometry& geometry, const TriangleBlock<8>* blocks, std::uint32_t count,
                      float margin, TriangleBlock<8>& header);

// The header's boxes as a node's bounds array.
[[nodiscard]] inline const float* leaf_boxes(const TriangleBlock<8>& header) {
    return &header.vertex[0][0][0];
}

// A ray as the wide box test reads it. The slab test picks each axis's entry plane by the sign of the
// reciprocal direction (pbrt-v3's dirIsNeg) instead of taking min/max of the two planes: an inverted empty
// slot then enters at +inf and leaves at -inf, a miss, where min/max would turn it into the unbounded box.
// For every box with lo <= hi both forms give the same two plane distances.
struct WideRay {
    Vec3f origin;
    Vec3f inv_direction;
    // Per axis, the side of the box the ray enters by: kHi (1) where the direction is negative or -0, else
    // kLo.
    std::array<int, 3> entry_side;

    // Always inlined: once per ray, and GCC's unit-growth limit has left it an out-of-line call (bvh8 lost a
    // quarter of its speed to that when an unrelated kernel in the same file grew).
    [[gnu::always_inline]] explicit WideRay(const SlabRay& slab)
        : origin(slab.origin), inv_direction(slab.inv_direction) {
        for (int axis = 0; axis < 3; ++axis)
            entry_side[axis] = std::signbit(inv_direction[axis]) ? 1 : 0;
    }
};

// The slab test of intersect_box on every child of `node`, one child at a time: bit i of the result is set
// when child i is hit within [tnear, tfar], with entry[i] its entry distance. The NaN rule of intersect_box
// (a ray in a face plane, 0 * inf, has that slab unbounded) holds per plane: a NaN plane distance leaves the
// interval as it is, because max(nan, t) and min(nan, t) are written to return t. Where one plane distance
// of an axis is NaN the other is +-inf on the side that does not clip, so this equals dropping the slab.
template <int W>
[[nodiscard]] inline unsigned intersect_children_scalar(const WideBvhNode<W>& node, const WideRay& ray,
                                                        float tnear, float tfar, float (&entry)[W]) {
    unsigned mask = 0;
    for (int slot = 0; slot < W; ++slot) {
        float t0 = tnear, t1 = tfar;
        for (int axis = 0; axis < 3; ++axis) {
            const int side = ray.entry_side[axis];
            const float near_plane =
                (node.bounds[side][axis][slot] - ray.origin[axis]) * ray.inv_direction[axis];
            const float far_plane = widened_slab_exit((node.bounds[1 - side][axis][slot] - ray.origin[axis]) *
                                                      ray.inv_direction[axis]);
            t0 = near_plane > t0 ? near_plane : t0;  // maxps operand order: NaN keeps t0
            t1 = far_plane < t1 ? far_plane : t1;    // minps operand order: NaN keeps t1
        }
        entry[slot] = t0;
        if (t0 <= t1) mask |= 1u << slot;
    }
    return mask;
}

// One slab of the box test on Ops::kWidth lanes: [t0, t1] clipped by the distances to the planes at
// near_bound and far_bound, the far one widened (widened_slab_exit, lane by lane: the factor chosen by the
// distance's sign). _mm*_max_ps(a, b) and _mm*_min_ps(a, b) return b when either is NaN: with the plane
// distance first, a NaN plane (0 * inf) leaves the interval as it is, as in intersect_children_scalar. The
// wide BVH's child test, the binary BVH's packets and bvh8_packet's groups all take their slabs here.
// kForward: every ray has tnear >= 0, so a box whose exit distance is negative is missed however it is
// widened (the sign of fl(b - o) * r is exact): the exit is multiplied by kSlabExitGrow without the
// select, two operations fewer on the walk's critical path.
template <class Ops, bool kForward = false>
inline void clip_slab(typename Ops::Float near_bound, typename Ops::Float far_bound,
                      typename Ops::Float origin, typename Ops::Float inv_direction, typename Ops::Float& t0,
                      typename Ops::Float& t1) {
    const auto near_plane = Ops::mul(Ops::sub(near_bound, origin), inv_direction);
    const auto far_distance = Ops::mul(Ops::sub(far_bound, origin), inv_direction);
    const auto far_plane =
        kForward ? Ops::mul(far_distance, Ops::broadcast(kSlabExitGrow))
                 : Ops::mul(far_distance, Ops::select_if_greater(far_distance, Ops::broadcast(0.0f),
                                                                 Ops::broadcast(kSlabExitGrow),
                                                                 Ops::broadcast(kSlabExitShrink)));
    t0 = Ops::max(near_plane, t0);
    t1 = Ops::min(far_plane, t1);
}

#if defined(__AVX2__) || defined(__SSE4_1__)
namespace wide_detail {

// Always inlined: it runs at every node of the walk, and GCC's inlining budget left it an out-of-line call
// (the ray's planes then go through memory at every node).
template <class Ops, bool kForward>
[[nodiscard, gnu::always_inline]] inline unsigned intersect_children_simd(const float* lo_hi,
                                                                          const WideRay& ray, float tnear,
                                                                          float tfar, float* entry) {
    using Float = typename Ops::Float;
    constexpr int width = Ops::kWidth;
    Float t0 = Ops::broadcast(tnear), t1 = Ops::broadcast(tfar);
    for (int axis = 0; axis < 3; ++axis) {
        const int side = ray.entry_side[axis];
        clip_slab<Ops, kForward>(
            Ops::load(lo_hi + (side * 3 + axis) * width), Ops::load(lo_hi + ((1 - side) * 3 + axis) * width),
            Ops::broadcast(ray.origin[axis]), Ops::broadcast(ray.inv_direction[axis]), t0, t1);
    }
    Ops::store(entry, t0);
    return Ops::bits(Ops::less_equal(t0, t1));
}

}  // namespace wide_detail
#endif

// The wide box test the traversal uses: SSE for 4 children and AVX2 for 8 where the compiler targets them
// (the AVX2 baseline, docs/isa.md), intersect_children_scalar otherwise. Same hits and entry distances either
// way (kForward, for tnear >= 0 only: clip_slab).
template <int W, bool kForward = false>
[[nodiscard, gnu::always_inline]] inline unsigned intersect_children(const WideBvhNode<W>& node,
                                                                     const WideRay& ray, float tnear,
                                                                     float tfar, float (&entry)[W]) {
#if defined(__SSE4_1__)
    if constexpr (W == 4) {
        return wide_detail::intersect_children_simd<simd::Sse4, kForward>(&node.bounds[0][0][0], ray, tnear,
                                                                          tfar, entry);
    }
#endif
#if defined(__AVX2__)
    if constexpr (W == 8) {
        return wide_detail::intersect_children_simd<simd::Avx2, kForward>(&node.bounds[0][0][0], ray, tnear,
                                                                          tfar, entry);
    }
#endif
    return intersect_children_scalar(node, ray, tnear, tfar, entry);
}

// The children in `mask` ordered by their entry distance, nearest first, into order[0, count); returns
// count. An insertion sort: at most W children, mostly 1 to 3, where a sorting network would do every
// compare-exchange. The single-ray walk and bvh8_packet's both visit children front to back with it.
template <int W>
[[nodiscard]] inline int order_by_entry(unsigned mask, const float (&entry)[W], std::array<int, W>& order) {
    int count = 0;
    for (; mask != 0; mask &= mask - 1) {
        const int slot = std::countr_zero(mask);
        int position = count++;
        for (; position > 0 && entry[order[position - 1]] > entry[slot]; --position)
            order[position] = order[position - 1];
        order[position] = slot;
    }
    return count;
}

// The children of `mask` in slot order into order[0, count), count returned: occlusion's order in
// bvh8_packet's packets and streams, where any hit ends a ray and the order only decides where the first is
// found.
template <std::size_t N>
[[nodiscard]] inline int order_by_slot(unsigned mask, std::array<int, N>& order) {
    int count = 0;
    for (; mask != 0; mask &= mask - 1)
        order[static_cast<std::size_t>(count++)] = std::countr_zero(mask);
    return count;
}

// The hit children of a node in the walk's order: each child but the nearest pushed, farthest first, and
// the nearest's slot returned (equal entries in slot order, as order_by_entry). `mask` is not empty.
// push(slot, counted) writes the child at the stack's top and grows the stack only when `counted`. One or
// two children, nine nodes in ten on incoherent rays and about 70 / 30 between the two, then go without a
// branch on which it is (docs/accel/bvh_wide.md, "One or two hit children without a branch"). Three or more
// take the insertion sort. The wide BVH's walk and the instances' top level both visit children so.
template <int W, class Push>
[[gnu::always_inline]] inline int push_farther_children(unsigned mask, const float (&entry)[W], Push&& push) {
    const int first_slot = std::countr_zero(mask);
    const unsigned rest = mask & (mask - 1);
    if ((rest & (rest - 1)) == 0) {
        // One child or two: the second is the first again when there is none, and then goes uncounted.
        const int second_slot = rest != 0 ? std::countr_zero(rest) : first_slot;
        const bool swap = entry[second_slot] < entry[first_slot];
        push(swap ? first_slot : second_slot, rest != 0);
        return swap ? second_slot : first_slot;
    }
    std::array<int, W> order;
    const int count = order_by_entry<W>(mask, entry, order);
    for (int k = count - 1; k > 0; --k)
        push(order[static_cast<std::size_t>(k)], true);
    return order[0];
}

template <int W>
class WideBvhAccel final : public SingleRayAccel<WideBvhAccel<W>> {
  public:
    static_assert(W == 4 || W == 8);
    // Primitives per leaf block: one SSE vector for bvh4, one AVX2 vector for bvh8.
    static constexpr int kBlockLanes = W;
    using Block = TriangleBlock<kBlockLanes>;

    [[nodiscard]] std::string_view name() const override { return W == 4 ? "bvh4" : "bvh8"; }
    [[nodiscard]] AccelStats stats() const override;
    [[nodiscard]] std::size_t memory_bytes() const override;
    [[nodiscard]] UpdateMethod update_method() const override;

    // The built hierarchy, for tests. The root is node 0 whenever the geometry is not empty.
    [[nodiscard]] const HugePageVector<WideBvhNode<W>>& nodes() const { return nodes_; }
    [[nodiscard]] const HugePageVector<Block>& blocks() const { return blocks_; }

  private:
    friend SingleRayAccel<WideBvhAccel<W>>;
    using SingleRayAccel<WideBvhAccel<W>>::geometry_;
    using SingleRayAccel<WideBvhAccel<W>>::build_ms_;
    using SingleRayAccel<WideBvhAccel<W>>::options_;

    void build_from(const Geometry& geometry, const BuildOptions& options);
    // The binary BVH's update: a refit, or a rebuild past bvh.refit_threshold or with spatial splits.
    UpdateReport update_from(const Geometry& geometry);
    // SingleRayAccel's contract.
    template <bool kAnyHit, bool kCount, class TriangleTestT>
    bool trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counts) const;

    HugePageVector<WideBvhNode<W>> nodes_;
    HugePageVector<Block> blocks_;
    double built_sah_cost_ = 0.0;  // the SAH cost as last built
    double sah_ratio_ = 1.0;       // the present SAH cost over built_sah_cost_
};

extern template class SingleRayAccel<WideBvhAccel<4>>;
extern template class SingleRayAccel<WideBvhAccel<8>>;
extern template class WideBvhAccel<4>;
extern template class WideBvhAccel<8>;
using Bvh4Accel = WideBvhAccel<4>;
using Bvh8Accel = WideBvhAccel<8>;

}  // namespace lancer
