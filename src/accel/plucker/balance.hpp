// The regularity constraint of Portalez & Duguet 2016, section 2.2 ("la difference de profondeur entre deux
// voisins ne peut exceder 1"), applied to the octree of octree_build.hpp, and the face-neighbour queries that
// the links and the balance share.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "accel/octree_build.hpp"

namespace lancer::plucker {

// The deepest cell of the tree that contains the cell (level, x, y, z) (itself when it exists), found by a
// descent from the root along the coordinate bits: O(level).
[[nodiscard]] std::uint32_t find_cell(const Octree& octree, int level, std::uint32_t x, std::uint32_t y,
                                      std::uint32_t z);

// The cells across one face of a cell: at most four, held in place (the layout asks for six lists a leaf).
struct FaceNeighbours {
    std::array<std::uint32_t, 4> cells{};
    std::uint32_t count = 0;

    [[nodiscard]] std::size_t size() const { return count; }
    [[nodiscard]] const std::uint32_t* begin() const { return cells.data(); }
    [[nodiscard]] const std::uint32_t* end() const { return cells.data() + count; }
};

// The cells across face `face` (conventions.hpp) of cell `cell`: none on the root's boundary; one when
// the deepest cell holding the same-level neighbour position is a leaf (same level or coarser) or when
// `same_or_larger` is set; else the four children of that same-level cell that touch the face, in
// sub-face order (they are leaves in a balanced tree).
[[nodiscard]] FaceNeighbours face_neighbours(const Octree& octree, std::uint32_t cell, int face,
                                             bool same_or_larger);

// Splits leaves until no two face-adjacent leaves differ by more than one level. Leaves are visited from
// the deepest level up: a leaf of level L forces the cell holding its face-neighbour position at level L - 1
// to exist, splitting coarser leaves with split_references (their children are visited later, at their own
// level). Forced splits ignore leaf_size and split_separates_nothing; they never go deeper than L - 1, so
// max_depth holds. Deterministic. References are compacted afterwards, leaf after leaf in cell order.
void balance_octree(const Geometry& geometry, Octree& octree);

// Whether every pair of face-adjacent leaves differs by at most one level (for tests; the layout refuses a
// tree that is not).
[[nodiscard]] bool is_balanced(const Octree& octree);

}  // namespace lancer::plucker
