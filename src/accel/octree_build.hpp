// The top-down octree build (the "Lancer de rayon" slides, "grille adaptative : octree"; Portalez & Duguet
// 2016, section 2.2), shared by the classic octree (octree.hpp, Revelles et al. 2000 traversal) and the
// Plücker-connected octree of Portalez & Duguet 2016, which adds a 2:1 balance and neighbour links on top of
// this node array.
//
// Cells are cubes. A cell of level l with integer coordinates (x, y, z), each in [0, 2^l), spans
//   [root.lo + root.size * (x, y, z) / 2^l, root.lo + root.size * (x + 1, y + 1, z + 1) / 2^l]
// on the three axes (OctreeCube::plane computes these coordinates so that a parent's mid plane and its
// children's faces are the same float). Child order: child index = x_bit | y_bit << 1 | z_bit << 2, where a
// bit is 1 for the upper half of the parent on that axis; child coordinates = 2 * parent + bits.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "core/host_device.hpp"
#include "lancer/accel.hpp"
#include "lancer/box.hpp"
#include "lancer/scene.hpp"

namespace lancer {

// The options of `octree` (the "Lancer de rayon" slides; Revelles et al. 2000): a node is split while depth <
// max_depth and it holds more than leaf_size references.
struct OctreeOptions {
    static constexpr std::string_view kGroup = "octree";
    int max_depth = 10;
    int leaf_size = 8;
};

// Deepest level the build reaches, whatever OctreeOptions::max_depth asks: coordinates fit 16 bits, and a
// level-16 cell is still 2^8 float ulps of a coordinate as large as the root, so its faces stay distinct.
inline constexpr int kOctreeMaxLevel = 16;
inline constexpr std::uint32_t kOctreeNoChild = 0xFFFFFFFFu;
// The narrowest cell the build makes, in the scene's geometric tolerance (Octree::tolerance). A cell
// references every primitive that touches its box grown by the tolerance (Octree::reference_box), so a cell
// only a few tolerances wide references those of a region several times its width, and splitting it copies
// references rather than separating them. The tolerance is 2^-20 of the largest coordinate plus 2^-19 of the
// scene's side, so this binds only on scenes far from the origin for their size: before kOctreeMaxLevel
// where the largest coordinate exceeds twice the side, before the default depth 10 where it exceeds 254
// sides (docs/accel/octree.md, "Build").
inline constexpr float kSmallestCellInTolerances = 4.0f;

// 20 bytes; the build's output, kept whole by structures that need positions (the Plücker octree's
// balance and links) and converted to the 8-byte OctreeNode (octree.hpp) for Revelles' traversal.
struct OctreeCell {
    std::uint32_t first_child = kOctreeNoChild;  // 4: index of child 0, the 8 children are contiguous
    std::uint32_t ref_begin = 0;                 // 4: leaves: [ref_begin, ref_end) in Octree::references
    std::uint32_t ref_end = 0;                   // 4: inner cells: empty range
    std::uint16_t x = 0, y = 0, z = 0;           // 6: integer coordinates at `level`
    std::uint8_t level = 0;                      // 1
    std::uint8_t padding = 0;                    // 1

    [[nodiscard]] bool is_leaf() const { return first_child == kOctreeNoChild; }
    [[nodiscard]] std::uint32_t ref_count() const { return ref_end - ref_begin; }
    [[nodiscard]] std::uint32_t coordinate(int axis) const { return axis == 0 ? x : (axis == 1 ? y : z); }
};
static_assert(sizeof(OctreeCell) == 20);

// The root cube and the coordinates of every cell face.
struct OctreeCube {
    Vec3f lo;
    float size = 0.0f;

    // Coordinate on `axis` of face i of the cells of `level` (i in [0, 2^level]). The fraction i / 2^level
    // is exact, so the same face reached from any level is the same float: a parent's mid plane is exactly
    // its children's shared face, and the traversal's slab distances match the build's boxes bit for bit.
    [[nodiscard]] LANCER_HOST_DEVICE float plane(int axis, int level, std::uint32_t i) const {
        return lo[axis] + size * (static_cast<float>(i) * inverse_power_of_two(level));
    }
    [[nodiscard]] Box3f cell_box(int level, std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
        return {{plane(0, level, x), plane(1, level, y), plane(2, level, z)},
                {plane(0, level, x + 1), plane(1, level, y + 1), plane(2, level, z + 1)}};
    }
};

// The smallest cube with corner lo = bounds.lo whose faces (as OctreeCube::plane rounds them) enclose
// `bounds`: its side is the largest extent, nudged up until rounding no longer cuts a primitive off.
// Anchoring at lo rather than centring keeps a flat scene on the root's face instead of on its mid plane,
// where every primitive would be referenced on both sides. An empty box gives the unit cube at the origin.
[[nodiscard]] OctreeCube octree_root_cube(const Box3f& bounds);

struct Octree {
    OctreeCube cube;
    float tolerance = 0.0f;                 // geometric_tolerance of the scene: cells are grown by it
    std::vector<OctreeCell> cells;          // cells[0] is the root
    std::vector<std::uint32_t> references;  // global primitive indices, leaf after leaf
    int max_depth = 0;                      // the depth limit the build used (options clamped)

    [[nodiscard]] Box3f cell_box(const OctreeCell& cell) const {
        return cube.cell_box(cell.level, cell.x, cell.y, cell.z);
    }
    // The box whose overlapping primitives a cell references.
    [[nodiscard]] Box3f reference_box(const Box3f& cell_box) const { return cell_box.grown(tolerance); }
};

// Top-down, depth first: a cell is split while level < max_depth (clamped to [0, kOctreeMaxLevel], then by
// deepest_separating_level) and it holds more than leaf_size references; a child references every
// primitive that primitive_overlaps_box says may touch its closed box grown by the scene's geometric
// tolerance (docs/numerical-contract.md, "Boxes": a hit the kernel reports a hair outside the cell it lies
// in is still found there). A split is also refused when it separates nothing (split_separates_nothing).
// Deterministic: references stay in increasing order. With oneTBB, subtrees of more than 4,096 references
// build in parallel and are spliced in child order: the same arrays whatever the thread count
// (docs/accel/parallel-build.md).
[[nodiscard]] Octree build_octree(const Geometry& geometry, const OctreeOptions& options);

// The depth limit build_octree uses: `max_depth`, or less where cells of that level would be narrower than
// kSmallestCellInTolerances tolerances.
[[nodiscard]] int deepest_separating_level(const OctreeCube& cube, float tolerance, int max_depth);

// The references each of the 8 children of `cell` would receive (child order above), in increasing order.
// build_octree splits with it; tests use it to check the stopping rule.
[[nodiscard]] std::array<std::vector<std::uint32_t>, 8> split_references(
    const Geometry& geometry, const Octree& octree, const OctreeCell& cell,
    std::span<const std::uint32_t> references);

// The stopping rule for coincident primitives: the split leaves every non-empty child with all of the
// cell's references, and at least two such children. Splitting again could only copy the same list into
// more cells, level after level (3000 coincident triangles: about 1e5 cells of 3000 references at depth
// 10). A single non-empty child is not refused: it zooms into an octant without copying anything, and
// deeper levels may still separate its references.
[[nodiscard]] bool split_separates_nothing(const std::array<std::vector<std::uint32_t>, 8>& children,
                                           std::size_t parent_count);

}  // namespace lancer
