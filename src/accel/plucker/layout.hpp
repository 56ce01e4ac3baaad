// The trace-time arrays of the Plücker octree (Portalez & Duguet 2016, section 3): the cells as a stream of
// 32-bit words (a leaf's are equation (3)'s, with running ends of the neighbour lists instead of counts), the
// triangles in leaf order, the cell boxes and the boundary cube map, plus the point-location tree that rays
// starting inside the root need. Plain data: this is also the on-disk layout (serialise.hpp). Each deviation
// from the seed and its reason: docs/accel/plucker.md, "Layout".
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "accel/octree_build.hpp"
#include "core/host_device.hpp"
#include "lancer/accel.hpp"
#include "lancer/box.hpp"

namespace lancer::plucker {

// A neighbour word is the address (word index) of the neighbour's first word. In the unconstrained variant a
// link may point at an inner cell (kInnerBit set): its record is the box word(s) and the 8 children's links,
// and the walk descends it (walk.hpp).
inline constexpr std::uint32_t kInnerBit = 0x80000000u;
inline constexpr std::uint32_t kAddressMask = 0x7FFFFFFFu;

// Word offsets in a leaf record.
inline constexpr std::uint32_t kTriangleCount = 0;
inline constexpr std::uint32_t kTriangleOffset = 1;
inline constexpr std::uint32_t kBoxWord = 2;  // stored boxes: the box index; else x | y << 16
// No stored boxes: word kBoxWord + 1 holds z | level << 16.
[[nodiscard]] constexpr std::uint32_t header_words(bool stored_boxes) {
    return stored_boxes ? 4u : 5u;
}
// Number of words describing the geometry of a cell (leaf or inner record).
[[nodiscard]] constexpr std::uint32_t box_words(bool stored_boxes) {
    return stored_boxes ? 1u : 2u;
}

// The running ends of the six neighbour lists, 5 bits each (at most 24 neighbours in all).
[[nodiscard]] constexpr std::uint32_t neighbour_start(std::uint32_t ends, int face) {
    return static_cast<std::uint32_t>((static_cast<std::uint64_t>(ends) << 5) >> (5 * face)) & 31u;
}
[[nodiscard]] constexpr std::uint32_t neighbour_end(std::uint32_t ends, int face) {
    return (ends >> (5 * face)) & 31u;
}

// The plane by which the walk leaves a cell through face i of `level` on `axis`: the exact float of
// OctreeCube::plane, but on the root's boundary (i = 0 or 2^level) the root's face grown by the tolerance,
// the box in which the entry accepts rays (walk.hpp). A ray within the tolerance outside a root face, moving
// away from it by less than a float per unit, would leave the root through the exact face at once and miss a
// hit the triangle test reports in that margin; through the grown face it goes on along the boundary cells
// until it leaves the grown root (docs/numerical-contract.md, "Boxes").
[[nodiscard]] LANCER_HOST_DEVICE inline float exit_plane_of(const OctreeCube& cube, float tolerance, int axis,
                                                            int level, std::uint32_t i) {
    if (i == 0) return cube.plane(axis, 0, 0) - tolerance;
    if (i == 1u << level) return cube.plane(axis, 0, 1) + tolerance;
    return cube.plane(axis, level, i);
}

// The cell of `level` holding coordinate p on `axis`, with a coordinate exactly on a plane between two cells
// given to the cell on the ray's side (up: [lo, hi), down: (lo, hi]). Clamped to the root.
[[nodiscard]] LANCER_HOST_DEVICE inline std::uint32_t cell_index(const OctreeCube& cube, int axis,
                                                                 std::uint32_t level, float p,
                                                                 std::uint32_t up) {
    const std::uint32_t last = (1u << level) - 1u;
    const float scaled = (p - cube.lo[axis]) / cube.size * static_cast<float>(1u << level);
    // NaN (a root cube of size 0: the scene is one point; fuzz/rays_fuzz.cpp) starts at 0 like a negative
    // estimate: converting it would be undefined, and the exact planes below settle the index either way.
    std::uint32_t i =
        !(scaled > 0.0f) ? 0u : min_of(last, static_cast<std::uint32_t>(min_of(scaled, 65536.0f)));
    // The estimate may be off by one near a plane: settle it against the exact planes.
    const int l = static_cast<int>(level);
    while (i > 0 && (up ? p < cube.plane(axis, l, i) : p <= cube.plane(axis, l, i)))
        --i;
    while (i < last && (up ? p >= cube.plane(axis, l, i + 1) : p > cube.plane(axis, l, i + 1)))
        ++i;
    return i;
}

// 36 bytes: a cell's lower corner, mid planes and upper corner, each the exact float of OctreeCube::plane
// (exit_plane_of for the corners), so that a cell's exit plane is bit for bit its neighbour's entry plane
// and its mid planes are its finer neighbours' shared faces. The seed stores 16 bytes per box; the mid planes
// are what the sub-face test (section 4.2.2) needs, and lo + size / 2 would round differently from the
// neighbours' own faces.
struct PluckerBox {
    std::array<float, 9> planes;  // lo.xyz, mid.xyz, hi.xyz

    [[nodiscard]] float lo(int axis) const { return planes[static_cast<std::size_t>(axis)]; }
    [[nodiscard]] float mid(int axis) const { return planes[static_cast<std::size_t>(3 + axis)]; }
    [[nodiscard]] float hi(int axis) const { return planes[static_cast<std::size_t>(6 + axis)]; }
};
static_assert(sizeof(PluckerBox) == 36);

// 40 bytes: one leaf's copy of a triangle (the seed's "triangles" array, in leaf order, so that a leaf's
// triangles are read in one sweep) and its global primitive index. A sphere reference keeps only the index
// (the sphere is read from the geometry); its triangle stays zero.
struct PluckerPrimitive {
    Triangle triangle;   // 36
    std::uint32_t prim;  // 4
};
static_assert(sizeof(PluckerPrimitive) == 40);

// The boundary cube map (Portalez & Duguet 2016, section 3, Figure 3), on the faces of the geometry's bounds
// rather than the root's: for each face, a square of 2^level x 2^level texels, level the deepest leaf in the
// face's layer (the cells that hold the face's plane, ties to the side of the rays entering through it), each
// holding the address of the leaf of that layer that contains it. Texel (i, j) on face f covers in-face
// cells i (lower in-face axis) and j (upper) at that level; it is texels[offset[f] + i + (j << level[f])].
// The cube map stops at 2^10 x 2^10 texels per face (4 MiB, the seed's 24 MB for the dragon over six
// faces); a texel that covers several deeper leaves holds the inner cell of that level covering it, tagged
// with kInnerBit, and the entry descends from there (walk.hpp).
inline constexpr std::uint32_t kMaxCubeMapLevel = 10;

struct CubeMap {
    std::array<std::uint32_t, 6> level{};
    std::array<std::uint32_t, 6> offset{};
    std::vector<std::uint32_t> texels;
};

struct PluckerLayoutOptions {
    bool stored_boxes = true;
    bool balanced = true;
    bool morton = false;
};

struct PluckerLayout {
    PluckerLayoutOptions options;
    OctreeCube cube;
    float tolerance = 0.0f;
    // The geometry's bounds grown by the tolerance (the root, for an empty geometry): the root is a cube
    // anchored at their lower corner, and a ray walks only the part of it inside them (walk.hpp's
    // entry_leaf). Made from the geometry, not stored in a file.
    Box3f bounds;
    std::uint32_t triangle_count = 0;  // primitives below it are triangles, the rest spheres
    std::vector<std::uint32_t> cells;  // the word stream
    std::vector<PluckerPrimitive> primitives;
    std::vector<PluckerBox> boxes;  // empty without stored boxes
    CubeMap cube_map;
    // Point location for rays that start inside the bounds, one word per cell of the tree (the build's cell
    // order): inner: first child << 1 | 1; leaf: its address << 1.
    std::vector<std::uint32_t> locate;
};

}  // namespace lancer::plucker
