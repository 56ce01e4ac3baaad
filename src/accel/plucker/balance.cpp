#include "accel/plucker/balance.hpp"

#include <utility>

#include "accel/plucker/conventions.hpp"

namespace lancer::plucker {
namespace {

// The same-level neighbour position across `face`; false on the root's boundary.
bool neighbour_position(const OctreeCell& cell, int face, std::array<std::uint32_t, 3>& position) {
    const int axis = face_axis(face);
    position = {cell.x, cell.y, cell.z};
    const std::uint32_t last = (1u << cell.level) - 1u;
    if (face_side(face) == 1) {
        if (position[static_cast<std::size_t>(axis)] == last) return false;
        ++position[static_cast<std::size_t>(axis)];
    } else {
        if (position[static_cast<std::size_t>(axis)] == 0) return false;
        --position[static_cast<std::size_t>(axis)];
    }
    return true;
}

void split_leaf(const Geometry& geometry, Octree& octree, std::uint32_t leaf,
                std::vector<std::vector<std::uint32_t>>& leaves_by_level) {
    const OctreeCell cell = octree.cells[leaf];
    const std::vector<std::uint32_t> references(octree.references.begin() + cell.ref_begin,
                                                octree.references.begin() + cell.ref_end);
    auto children = split_references(geometry, octree, cell, references);
    const auto first_child = static_cast<std::uint32_t>(octree.cells.size());
    octree.cells[leaf].first_child = first_child;
    octree.cells[leaf].ref_begin = octree.cells[leaf].ref_end = 0;
    for (std::uint32_t child = 0; child < 8; ++child) {
        OctreeCell child_cell;
        child_cell.x = static_cast<std::uint16_t>(2u * cell.x + (child & 1u));
        child_cell.y = static_cast<std::uint16_t>(2u * cell.y + ((child >> 1) & 1u));
        child_cell.z = static_cast<std::uint16_t>(2u * cell.z + ((child >> 2) & 1u));
        child_cell.level = static_cast<std::uint8_t>(cell.level + 1);
        child_cell.ref_begin = static_cast<std::uint32_t>(octree.references.size());
        octree.references.insert(octree.references.end(), children[child].begin(), children[child].end());
        child_cell.ref_end = static_cast<std::uint32_t>(octree.references.size());
        octree.cells.push_back(child_cell);
        leaves_by_level[child_cell.level].push_back(first_child + child);
    }
}

// References leaf after leaf in cell order, dropping the ranges of the leaves that were split.
void compact_references(Octree& octree) {
    std::vector<std::uint32_t> compacted;
    compacted.reserve(octree.references.size());
    for (OctreeCell& cell : octree.cells) {
        if (!cell.is_leaf()) continue;
        const auto begin = static_cast<std::uint32_t>(compacted.size());
        compacted.insert(compacted.end(), octree.references.begin() + cell.ref_begin,
                         octree.references.begin() + cell.ref_end);
        cell.ref_begin = begin;
        cell.ref_end = static_cast<std::uint32_t>(compacted.size());
    }
    octree.references = std::move(compacted);
}

}  // namespace

std::uint32_t find_cell(const Octree& octree, int level, std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    std::uint32_t index = 0;
    for (int l = 0; l < level; ++l) {
        const OctreeCell& cell = octree.cells[index];
        if (cell.is_leaf()) break;
        const int shift = level - l - 1;
        const std::uint32_t child = ((x >> shift) & 1u) | ((y >> shift) & 1u) << 1 | ((z >> shift) & 1u) << 2;
        index = cell.first_child + child;
    }
    return index;
}

FaceNeighbours face_neighbours(const Octree& octree, std::uint32_t cell_index, int face,
                               bool same_or_larger) {
    FaceNeighbours neighbours;
    const OctreeCell& cell = octree.cells[cell_index];
    std::array<std::uint32_t, 3> position;
    if (!neighbour_position(cell, face, position)) return neighbours;
    const std::uint32_t found = find_cell(octree, cell.level, position[0], position[1], position[2]);
    const OctreeCell& neighbour = octree.cells[found];
    if (neighbour.is_leaf() || same_or_larger) {
        neighbours.cells[0] = found, neighbours.count = 1;
        return neighbours;
    }
    // The same-level neighbour is subdivided: its children on the near side of the shared face.
    const int axis = face_axis(face);
    const std::uint32_t near_bit = face_side(face) == 1 ? 0u : 1u;
    const int u = lower_in_face_axis(axis), v = upper_in_face_axis(axis);
    for (std::uint32_t q = 0; q < 4; ++q) {
        const std::uint32_t child = near_bit << axis | (q & 1u) << u | ((q >> 1) & 1u) << v;
        neighbours.cells[q] = neighbour.first_child + child;
    }
    neighbours.count = 4;
    return neighbours;
}

void balance_octree(const Geometry& geometry, Octree& octree) {
    std::vector<std::vector<std::uint32_t>> leaves_by_level(kOctreeMaxLevel + 1);
    for (std::uint32_t i = 0; i < octree.cells.size(); ++i) {
        if (octree.cells[i].is_leaf()) leaves_by_level[octree.cells[i].level].push_back(i);
    }
    for (int level = kOctreeMaxLevel; level >= 2; --level) {
        // Splits add leaves at levels below `level` only, so this list does not grow while it is read.
        const std::vector<std::uint32_t>& leaves = leaves_by_level[static_cast<std::size_t>(level)];
        for (const std::uint32_t leaf : leaves) {
            if (!octree.cells[leaf].is_leaf()) continue;  // split since it was listed
            for (int face = 0; face < 6; ++face) {
                std::array<std::uint32_t, 3> position;
                if (!neighbour_position(octree.cells[leaf], face, position)) continue;
                while (true) {
                    const std::uint32_t found =
                        find_cell(octree, level - 1, position[0] >> 1, position[1] >> 1, position[2] >> 1);
                    if (octree.cells[found].level >= level - 1) break;
                    split_leaf(geometry, octree, found, leaves_by_level);
                }
            }
        }
    }
    compact_references(octree);
}

bool is_balanced(const Octree& octree) {
    for (std::uint32_t i = 0; i < octree.cells.size(); ++i) {
        const OctreeCell& cell = octree.cells[i];
        if (!cell.is_leaf()) continue;
        for (int face = 0; face < 6; ++face) {
            for (const std::uint32_t neighbour : face_neighbours(octree, i, face, false)) {
                const OctreeCell& other = octree.cells[neighbour];
                if (!other.is_leaf()) return false;
                const int difference = static_cast<int>(other.level) - static_cast<int>(cell.level);
                if (difference > 1 || difference < -1) return false;
            }
        }
    }
    return true;
}

}  // namespace lancer::plucker
