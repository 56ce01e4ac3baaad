// The plain-old-data arrays the GPU kernels read, and the views (pointers and counts) that the per-ray
// traversals take, shared by the host (flatten.cpp, the CPU tests) and the device (kernels.cu): Aila &
// Laine's 64-byte BVH nodes with triangles stored as vertices, so that the CPU's triangle tests run
// unchanged, and the Plücker octree's serialised arrays as they are (layout.hpp). Why each choice:
// docs/cuda.md, "Memory layout".
#pragma once

#include <cstdint>

#include "accel/plucker/walk.hpp"
#include "core/camera_ray.hpp"
#include "cuda/read_only_cache.hpp"
#include "lancer/scene.hpp"

namespace lancer::gpu {

// A child word: >= 0 the index of an inner node; < 0 a leaf, ~(first << kLeafCountBits | (count - 1)),
// first indexing `BvhView::triangles` (a leaf holds 1 to BvhAccel::kMaxLeafSize = 64 references).
inline constexpr int kLeafCountBits = 6;
inline constexpr std::uint32_t kMaxLeafReferences = 1u << kLeafCountBits;
inline constexpr std::uint32_t kMaxTriangleReferences = 1u << (31 - kLeafCountBits);

LANCER_HOST_DEVICE inline std::int32_t leaf_word(std::uint32_t first, std::uint32_t count) {
    return ~static_cast<std::int32_t>(first << kLeafCountBits | (count - 1u));
}
LANCER_HOST_DEVICE inline std::uint32_t leaf_first(std::int32_t word) {
    return static_cast<std::uint32_t>(~word) >> kLeafCountBits;
}
LANCER_HOST_DEVICE inline std::uint32_t leaf_count(std::int32_t word) {
    return (static_cast<std::uint32_t>(~word) & (kMaxLeafReferences - 1u)) + 1u;
}

// 64 bytes, one L1 line's half on the GPU, fetched as four float4: Aila-Laine's order (both x/y ranges,
// then both z ranges, then the links).
struct AilaLaineNode {
    float c0_lo_x, c0_hi_x, c0_lo_y, c0_hi_y;  // 16
    float c1_lo_x, c1_hi_x, c1_lo_y, c1_hi_y;  // 16
    float c0_lo_z, c0_hi_z, c1_lo_z, c1_hi_z;  // 16
    std::int32_t child[2];                     //  8: child words (see leaf_word)
    std::int32_t padding[2];                   //  8: zero
};
static_assert(sizeof(AilaLaineNode) == 64);

// 40 bytes: a leaf's triangle and its global primitive index (the Plücker octree's PluckerPrimitive).
struct TriangleRef {
    Triangle triangle;   // 36
    std::uint32_t prim;  // 4
};
static_assert(sizeof(TriangleRef) == 40);

struct BvhView {
    const AilaLaineNode* nodes = nullptr;  // node 0 is the root; none for an empty scene
    std::uint32_t node_count = 0;
    const TriangleRef* triangles = nullptr;
};

// A frame's rays are numbered by tiles of 8 x 4 pixels, one warp each (Aila & Laine's primary rays: a
// warp's rays stay coherent), tiles row by row. Indices past the film's edges name no pixel.
inline constexpr int kTileWidth = 8, kTileHeight = 4;

LANCER_HOST_DEVICE inline std::uint32_t frame_ray_count(const CameraFrame& camera) {
    const auto tiles_x = static_cast<std::uint32_t>((camera.width + kTileWidth - 1) / kTileWidth);
    const auto tiles_y = static_cast<std::uint32_t>((camera.height + kTileHeight - 1) / kTileHeight);
    return tiles_x * tiles_y * static_cast<std::uint32_t>(kTileWidth * kTileHeight);
}

// The pixel of ray `index`, false past the film's edges.
LANCER_HOST_DEVICE inline bool frame_pixel(const CameraFrame& camera, std::uint32_t index, int& x, int& y) {
    constexpr auto kTileSize = static_cast<std::uint32_t>(kTileWidth * kTileHeight);
    const auto tiles_x = static_cast<std::uint32_t>((camera.width + kTileWidth - 1) / kTileWidth);
    const std::uint32_t tile = index / kTileSize, within = index % kTileSize;
    x = static_cast<int>((tile % tiles_x) * kTileWidth + within % kTileWidth);
    y = static_cast<int>((tile / tiles_x) * kTileHeight + within / kTileWidth);
    return x < camera.width && y < camera.height;
}

}  // namespace lancer::gpu
