// The host side of the compressed wide BVH (cwbvh_layout.hpp), plain C++ (g++): bvh8's tree converted
// node for node, its child boxes quantized conservatively, its children put in octant order, its leaves
// made to fit the 32-bit triangle mask. docs/cuda.md, "The compressed wide BVH".
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "accel/bvh/bvh_wide.hpp"
#include "cuda/cwbvh_layout.hpp"
#include "lancer/scene.hpp"

namespace lancer::gpu {

struct CompressedWideBvh {
    std::vector<CwbvhNode> nodes;
    std::vector<TriangleRef> triangles;  // in leaf order
    // Leaves of bvh8 (or parts of one) made inner nodes of their own to fit the triangle mask.
    std::uint32_t split_leaves = 0;
    // The depth of the deepest node, the root's 0: the traversal's stack holds at most that many groups.
    int max_depth = 0;

    [[nodiscard]] CwbvhView view() const {
        return {nodes.data(), static_cast<std::uint32_t>(nodes.size()), triangles.data()};
    }
};

// `bvh8` (built on `geometry`, its built_geometry()) as a compressed wide BVH: the same inner nodes, in
// depth-first order of their parents with each node's inner children contiguous, and every leaf's
// triangles once, a leaf of more than kMaxLeafTriangles, or one whose node's leaves would exceed
// kMaxNodeTriangles, split into a node of its own. Throws std::invalid_argument for spheres (the GPU traces
// triangles), for 2^31 nodes or triangle references or more, and for a tree deeper than the traversal's
// stack (kCwbvhStackSize).
[[nodiscard]] CompressedWideBvh compress_bvh8(const WideBvhAccel<8>& bvh8, const Geometry& geometry);

// The origin, exponents and quantized bounds of `node` for the child boxes `boxes` (an empty box: an empty
// slot, quantized to 0): each decoded box (decoded_child_box) contains its child's box, checked with the
// traversal's own decode. Throws std::invalid_argument for a non-finite bound.
void quantize_child_boxes(const std::array<Box3f, kCwbvhWidth>& boxes, CwbvhNode& node);

}  // namespace lancer::gpu
