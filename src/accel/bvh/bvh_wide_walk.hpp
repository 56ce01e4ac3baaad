// The single-ray walk of the wide BVHs (bvh_wide.hpp): bvh4 and bvh8 trace with it, and bvh8_packet's
// interval cull (bvh8_packet_kernel.cpp) hands each ray of a thinned packet to it at the subtree where the
// packet parted. Beside it, the walk to every hit of a ray (GeometryQueries::all_hits). Both compilations of
// the packet kernel include it, so its code is in the instruction set's namespace (core/isa_namespace.hpp).
#pragma once

#include <array>
#include <bit>
#include <cstdint>
#include <vector>

#include "accel/bvh/bvh_wide.hpp"
#include "accel/primitive_intersect.hpp"
#include "core/isa_namespace.hpp"

namespace lancer {
inline namespace LANCER_ISA_NAMESPACE {
namespace wide_walk {

// A child as the traversal holds it: an inner node (prim_count 0) or a leaf's first block.
struct ChildRef {
    std::uint32_t child;
    std::uint32_t prim_count;
};

struct StackEntry {
    ChildRef ref;
    float t_entry;  // where the ray enters the child's box: the child is skipped once a hit is closer
};

// Starts the loads of a child that a walk will pop later: an inner node's lines, or a leaf's blocks.
// bvh8_packet's packets and streams request every child they push (docs/accel/packets.md, "Large meshes:
// prefetching the pushed children"; docs/accel/stream.md).
template <int W>
[[gnu::always_inline]] inline void prefetch_child(
    const HugePageVector<WideBvhNode<W>>& nodes,
    const HugePageVector<typename WideBvhAccel<W>::Block>& blocks, std::uint32_t child,
    std::uint32_t prim_count) {
    constexpr std::size_t kLine = 64;
    if (prim_count == 0) {
        const auto* bytes = reinterpret_cast<const char*>(&nodes[child]);
        for (std::size_t at = 0; at < sizeof(WideBvhNode<W>); at += kLine)
            __builtin_prefetch(bytes + at);
        return;
    }
    const std::uint32_t start = leaf_start(child);
    const auto* bytes = reinterpret_cast<const char*>(&blocks[start]);
    const std::size_t size =
        sizeof(typename WideBvhAccel<W>::Block) * (leaf_span<W>(child, prim_count).end - start);
    for (std::size_t at = 0; at < size; at += kLine)
        __builtin_prefetch(bytes + at);
}

// Each wide level pushes at most W - 1 children, and the wide tree is no deeper than the binary one.
// push_farther_children's uncounted write lands where the node's first push would: within the same bound.
template <int W>
constexpr int kStackSize = (W - 1) * BvhAccel::kMaxDepth + 1;

// Front to back, as the binary BVH (docs/accel/bvh.md): all W child boxes are tested at once, the hit ones
// are ordered by entry distance (insertion sort: ties keep slot order; occlusion keeps slot order), the
// nearest is visited and the others pushed, farthest first. A popped child is skipped when it is entered
// beyond the best hit. kForward: the ray has tnear >= 0, which allows clip_slab's cheaper exit widening.
// The walk starts at `start`, the root or the subtree where a packet hands the ray over (bvh8_packet's
// interval cull), with `best` the closest hit found before it.
template <int W, bool kAnyHit, bool kCount, bool kForward, class TriangleTestT>
bool traverse_from(const HugePageVector<WideBvhNode<W>>& nodes,
                   const HugePageVector<typename WideBvhAccel<W>::Block>& blocks, const Geometry& geometry,
                   const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counters,
                   ChildRef start = {0, 0}) {
    constexpr int kLanes = WideBvhAccel<W>::kBlockLanes;
    if (nodes.empty()) return false;
    const Ray& ray = prepared.ray;
    const WideRay wide_ray{SlabRay(ray)};
    const BlockRay<TriangleTestT, kLanes> block_ray(prepared, geometry);
    std::array<StackEntry, kStackSize<W>> stack;
    int stack_size = 0;
    ChildRef current = start;
    while (true) {
        if constexpr (kCount) ++counters.nodes_visited;
        if (current.prim_count > 0) {
            // LEAF: one SIMD test per block of kBlockLanes primitives. A header's block boxes
            // (has_leaf_boxes) are left to the ray streams: here the test would hold back the blocks' loads
            // until the header's own (docs/accel/bvh_wide.md, "Block boxes in merged leaves").
            const LeafSpan span = leaf_span<W>(current.child, current.prim_count);
            if constexpr (kCount) counters.prims_tested += current.prim_count;
            for (std::uint32_t b = span.first; b < span.end; ++b) {
                if constexpr (kAnyHit) {
                    if (occludes_block(geometry, blocks[b], block_ray)) return true;
                } else {
                    intersect_block(geometry, blocks[b], block_ray, best);
                }
            }
        } else {
            // INNER: test the W boxes, visit the nearest hit child, push the others.
            const WideBvhNode<W>& node = nodes[current.child];
            const float t_limit = best.hit() ? best.t : ray.tfar;
            alignas(32) float entry[W];
            const unsigned hit_mask =
                intersect_children<W, kForward>(node, wide_ray, ray.tnear, t_limit, entry);
            if constexpr (kAnyHit) {
                // Any hit ends the walk, so the order only decides where the first is found: the children
                // go in slot order, without the sort.
                if (hit_mask != 0) {
                    const int first_slot = std::countr_zero(hit_mask);
                    for (unsigned rest = hit_mask & (hit_mask - 1); rest != 0; rest &= rest - 1) {
                        const int slot = std::countr_zero(rest);
                        stack[stack_size++] = {{node.child[slot], node.prim_count[slot]}, entry[slot]};
                    }
                    current = {node.child[first_slot], node.prim_count[first_slot]};
                    continue;
                }
            } else if (hit_mask != 0) {
                const int nearest = push_farther_children<W>(hit_mask, entry, [&](int slot, bool counted) {
                    stack[stack_size] = {{node.child[slot], node.prim_count[slot]}, entry[slot]};
                    stack_size += counted ? 1 : 0;
                });
                current = {node.child[nearest], node.prim_count[nearest]};
                continue;
            }
        }
        // POP the next child that may still hold a hit no farther than the best one.
        do {
            if (stack_size == 0) return best.hit();
            const StackEntry popped = stack[--stack_size];
            current = popped.ref;
            if (!best.hit() || popped.t_entry <= best.t) break;
        } while (true);
    }
}

// The walk, with the box test's cheaper exit widening for the rays that start at tnear >= 0 (all but a few).
template <int W, bool kAnyHit, bool kCount, class TriangleTestT>
bool traverse(const HugePageVector<WideBvhNode<W>>& nodes,
              const HugePageVector<typename WideBvhAccel<W>::Block>& blocks, const Geometry& geometry,
              const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counters,
              ChildRef start = {0, 0}) {
    if (prepared.ray.tnear >= 0.0f)
        return traverse_from<W, kAnyHit, kCount, true>(nodes, blocks, geometry, prepared, best, counters,
                                                       start);
    return traverse_from<W, kAnyHit, kCount, false>(nodes, blocks, geometry, prepared, best, counters, start);
}

// Every hit of the ray, by on_hit(hit), in no particular order: every child box the ray crosses within
// [tnear, tfar] is entered (nothing is culled by a hit), a leaf's triangles a block at a time with the block
// kernel (the scalar kernel's bits) and its scalar lanes and spheres by the scalar test. A tree with spatial
// splits reports a primitive once per leaf that holds it.
template <int W, class TriangleTestT, class OnHit>
void all_hits(const HugePageVector<WideBvhNode<W>>& nodes,
              const HugePageVector<typename WideBvhAccel<W>::Block>& blocks, const Geometry& geometry,
              const PreparedRay<TriangleTestT>& prepared, OnHit&& on_hit) {
    constexpr int kLanes = WideBvhAccel<W>::kBlockLanes;
    if (nodes.empty()) return;
    const Ray& ray = prepared.ray;
    const WideRay wide_ray{SlabRay(ray)};
    const BlockRay<TriangleTestT, kLanes> block_ray(prepared, geometry);
    // A popped node pushes at most W children: the stack grows by at most W - 1 a level.
    std::array<ChildRef, kStackSize<W>> stack;
    int stack_size = 0;
    stack[stack_size++] = {0, 0};  // the root
    while (stack_size > 0) {
        const ChildRef current = stack[--stack_size];
        if (current.prim_count == 0) {
            const WideBvhNode<W>& node = nodes[current.child];
            alignas(32) float entry[W];
            for (unsigned mask = intersect_children<W>(node, wide_ray, ray.tnear, ray.tfar, entry); mask != 0;
                 mask &= mask - 1) {
                const int slot = std::countr_zero(mask);
                stack[stack_size++] = {node.child[slot], node.prim_count[slot]};
            }
            continue;
        }
        const LeafSpan span = leaf_span<W>(current.child, current.prim_count);
        for (std::uint32_t b = span.first; b < span.end; ++b)
            each_block_hit(geometry, blocks[b], block_ray, on_hit);
    }
}

}  // namespace wide_walk
}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
