#include "accel/octree_build.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <utility>

#include "accel/build_util.hpp"

namespace lancer {

OctreeCube octree_root_cube(const Box3f& bounds) {
    if (bounds.empty()) return {Vec3f(0.0f), 1.0f};
    OctreeCube cube{bounds.lo, max_component(bounds.extent())};
    // lo + (hi - lo) may round below hi: grow the side by ulps until every upper face reaches the box.
    for (int axis = 0; axis < 3; ++axis) {
        while (cube.plane(axis, 0, 1) < bounds.hi[axis])
            cube.size = std::nextafter(cube.size, kInfinity);
    }
    return cube;
}

namespace {

[[nodiscard]] bool boxes_overlap(const Box3f& a, const Box3f& b) {
    return a.lo.x <= b.hi.x && a.lo.y <= b.hi.y && a.lo.z <= b.hi.z && b.lo.x <= a.hi.x && b.lo.y <= a.hi.y &&
           b.lo.z <= a.hi.z;
}

}  // namespace

std::array<std::vector<std::uint32_t>, 8> split_references(const Geometry& geometry, const Octree& octree,
                                                           const OctreeCell& cell,
                                                           std::span<const std::uint32_t> references) {
    const int child_level = cell.level + 1;
    std::array<Box3f, 8> boxes;
    // A cheap bounds test before the separating-axis test. The box is grown twice: once is what
    // primitive_overlaps_box itself allows, the second margin (1e-6 relative) dwarfs the few ulps by which
    // its centre-relative arithmetic may differ from this absolute one, so the prefilter never rejects a
    // primitive the exact test would accept.
    std::array<Box3f, 8> loose;
    for (std::uint32_t child = 0; child < 8; ++child) {
        boxes[child] = octree.reference_box(octree.cube.cell_box(child_level, 2u * cell.x + (child & 1u),
                                                                 2u * cell.y + ((child >> 1) & 1u),
                                                                 2u * cell.z + ((child >> 2) & 1u)));
        loose[child] = grown_for_overlap(grown_for_overlap(boxes[child]));
    }
    std::array<std::vector<std::uint32_t>, 8> children;
    for (const std::uint32_t prim : references) {
        const Box3f bounds = primitive_bounds(geometry, prim);
        for (std::size_t child = 0; child < 8; ++child) {
            if (boxes_overlap(bounds, loose[child]) && primitive_overlaps_box(geometry, prim, boxes[child]))
                children[child].push_back(prim);
        }
    }
    return children;
}

bool split_separates_nothing(const std::array<std::vector<std::uint32_t>, 8>& children,
                             std::size_t parent_count) {
    // Children hold subsets of the parent's references, so a full child holds the same references.
    int full = 0;
    for (const std::vector<std::uint32_t>& child : children) {
        if (child.size() == parent_count)
            ++full;
        else if (!child.empty())
            return false;  // this child separates some references from the others
    }
    return full >= 2;
}

Octree build_octree(const Geometry& geometry, const OctreeOptions& options) {
    Octree octree;
    const Box3f bounds = geometry.bounds();
    octree.cube = octree_root_cube(bounds);
    octree.tolerance = geometric_tolerance(bounds);
    octree.max_depth = std::clamp(options.max_depth, 0, kOctreeMaxLevel);
    const auto leaf_size = static_cast<std::size_t>(std::max(options.leaf_size, 0));
    if (geometry.size() >= std::numeric_limits<std::uint32_t>::max())
        throw std::length_error("octree: primitive indices must fit 32 bits");

    struct Pending {
        std::uint32_t cell;
        std::vector<std::uint32_t> references;
    };
    std::vector<Pending> stack;
    octree.cells.emplace_back();
    std::vector<std::uint32_t> all(geometry.size());
    std::iota(all.begin(), all.end(), 0u);
    stack.push_back({0, std::move(all)});

    while (!stack.empty()) {
        Pending pending = std::move(stack.back());
        stack.pop_back();
        const OctreeCell cell = octree.cells[pending.cell];
        if (cell.level < octree.max_depth && pending.references.size() > leaf_size) {
            auto children = split_references(geometry, octree, cell, pending.references);
            if (!split_separates_nothing(children, pending.references.size())) {
                const auto first_child = static_cast<std::uint32_t>(octree.cells.size());
                octree.cells[pending.cell].first_child = first_child;
                for (std::uint32_t child = 0; child < 8; ++child) {
                    OctreeCell child_cell;
                    child_cell.x = static_cast<std::uint16_t>(2u * cell.x + (child & 1u));
                    child_cell.y = static_cast<std::uint16_t>(2u * cell.y + ((child >> 1) & 1u));
                    child_cell.z = static_cast<std::uint16_t>(2u * cell.z + ((child >> 2) & 1u));
                    child_cell.level = static_cast<std::uint8_t>(cell.level + 1);
                    octree.cells.push_back(child_cell);
                }
                // Reversed, so that child 0 is built first: depth-first order for cells and references.
                for (std::uint32_t child = 8; child-- > 0;)
                    stack.push_back({first_child + child, std::move(children[child])});
                continue;
            }
        }
        // LEAF
        if (octree.references.size() + pending.references.size() >= std::numeric_limits<std::uint32_t>::max())
            throw std::length_error("octree: more than 2^32 references");
        OctreeCell& leaf = octree.cells[pending.cell];
        leaf.ref_begin = static_cast<std::uint32_t>(octree.references.size());
        octree.references.insert(octree.references.end(), pending.references.begin(),
                                 pending.references.end());
        leaf.ref_end = static_cast<std::uint32_t>(octree.references.size());
    }
    return octree;
}

}  // namespace lancer
