// The compressed 8-wide BVH of Ylitie, Karras & Laine, "Efficient Incoherent Ray Traversal on GPUs Through
// Compressed Wide BVHs" (HPG 2017; their node format): 80-byte nodes whose child boxes are 8-bit
// offsets on a per-node, per-axis power-of-two grid, shared by the host (cwbvh_build.cpp, the CPU tests) and
// the device. Why each choice, and the leaf encoding that differs from the paper's: docs/cuda.md, "The
// compressed wide BVH".
//
// The leaf variant: the paper's leaves hold 1 to 3 triangles (a unary count) and a node's leaves 24 in all,
// addressed by the 24 low bits of its hit mask. bvh8's leaves hold up to 8 triangles (64 with
// bvh.max_leaf_size), so here a leaf's meta byte is its offset from the node's triangle base (5 bits) and its
// count less one (3 bits): a leaf holds 1 to 8 triangles and a node's leaves 32, a 32-bit triangle mask. The
// builder turns a leaf that would not fit (more than 8 triangles, or a node whose leaves exceed 32) into an
// inner child whose node splits it.
#pragma once

#include <cstdint>

#include "core/host_device.hpp"
#include "cuda/gpu_layout.hpp"
#include "lancer/box.hpp"

namespace lancer::gpu {

inline constexpr int kCwbvhWidth = 8;
// Quantized coordinates are 0..255: a child bound is origin + q * 2^exponent.
inline constexpr int kQuantizationSteps = 255;
// The exponents the traversal decodes: 2^e is a normal float, made from its bits.
inline constexpr int kMinExponent = -126, kMaxExponent = 127;
// A leaf's meta byte: bits 0-4 the offset of its first triangle from the node's triangle base, bits 5-7 its
// count less one.
inline constexpr int kLeafOffsetBits = 5;
inline constexpr std::uint32_t kMaxLeafTriangles = 8;
inline constexpr std::uint32_t kMaxNodeTriangles = 32;
// An empty slot's meta byte: offset 31 and 8 triangles would end past the node's 32, so no leaf has it.
inline constexpr std::uint8_t kEmptySlot = 0xFF;
// The traversal's stack holds at most one node group per level below the root: the depth of the deepest
// node. bvh8's stays below BvhAccel::kMaxDepth = 96 and split leaves add two levels (cwbvh_build.cpp checks
// both, and refuses a deeper tree).
inline constexpr int kCwbvhStackSize = 98;

// 80 bytes, five 16-byte words: the node's frame, then the links and meta bytes, then the boxes.
struct CwbvhNode {
    float origin[3];              // 12: p, the frame's origin: the lo corner of the union of the child boxes
    std::int8_t exponent[3];      //  3: e per axis, kMinExponent..kMaxExponent
    std::uint8_t inner_mask;      //  1: imask, bit s set when slot s holds an inner child
    std::uint32_t child_base;     //  4: the first inner child's node; the others follow in slot order
    std::uint32_t triangle_base;  //  4: the first triangle of the node's leaves, in slot order
    std::uint8_t meta[8];         //  8: a leaf's offset and count (above), kEmptySlot, 0 for an inner child
    std::uint8_t lo[3][8];        // 24: quantized lo per axis and slot, rounded down
    std::uint8_t hi[3][8];        // 24: quantized hi per axis and slot, rounded up
};
static_assert(sizeof(CwbvhNode) == 80);

struct CwbvhView {
    const CwbvhNode* nodes = nullptr;  // node 0 is the root; none for an empty scene
    std::uint32_t node_count = 0;
    const TriangleRef* triangles = nullptr;  // in leaf order
};

LANCER_HOST_DEVICE inline bool is_empty_slot(const CwbvhNode& node, int slot) {
    return ((node.inner_mask >> slot) & 1u) == 0 && node.meta[slot] == kEmptySlot;
}

// A leaf's bits in its node's triangle mask: `count` bits from `offset`.
LANCER_HOST_DEVICE inline std::uint32_t leaf_triangle_bits(std::uint8_t meta) {
    const std::uint32_t count = (static_cast<std::uint32_t>(meta) >> kLeafOffsetBits) + 1u;
    return (0xFFu >> (kMaxLeafTriangles - count)) << (meta & ((1u << kLeafOffsetBits) - 1u));
}
LANCER_HOST_DEVICE inline std::uint8_t leaf_meta(std::uint32_t offset, std::uint32_t count) {
    return static_cast<std::uint8_t>((count - 1u) << kLeafOffsetBits | offset);
}

// 2^exponent, a normal float for kMinExponent..kMaxExponent.
LANCER_HOST_DEVICE inline float quantization_scale(int exponent) {
    return inverse_power_of_two(-exponent);
}

// One decoded bound: origin + q * 2^e, the product exact (8 bits times a power of two, or +inf past the
// largest float), the sum rounded once. The builder checks its rounding with this same function; nothing may
// fuse it (nvcc --fmad=false, g++ -ffp-contract=off).
LANCER_HOST_DEVICE inline float decode_bound(float origin, std::uint8_t q, float scale) {
    return origin + static_cast<float>(q) * scale;
}

// The box slot `slot` decodes to: it contains the child's box (the builder's guarantee).
LANCER_HOST_DEVICE inline Box3f decoded_child_box(const CwbvhNode& node, const float (&scale)[3], int slot) {
    const auto bound = [&](const std::uint8_t(&q)[3][8], int axis) {
        return decode_bound(node.origin[axis], q[axis][slot], scale[axis]);
    };
    return {{bound(node.lo, 0), bound(node.lo, 1), bound(node.lo, 2)},
            {bound(node.hi, 0), bound(node.hi, 1), bound(node.hi, 2)}};
}

}  // namespace lancer::gpu
