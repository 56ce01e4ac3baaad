#include "accel/octree_build.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <utility>

#include "accel/build_util.hpp"
#include "core/parallel.hpp"

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

// Subtrees with more references than this are split by a task per child (TBB), and split_references
// sorts a cell's references among its children in blocks of this many, one task per block. Both thresholds
// depend on the data only, never on the thread count, so 1 and N threads build the same tree.
constexpr std::size_t kParallelSubtree = 4096;
constexpr std::size_t kSplitBlock = 16384;

void check_reference_count(std::size_t count) {
    if (count >= std::numeric_limits<std::uint32_t>::max())
        throw std::length_error("octree: more than 2^32 references");
}

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
    using ChildLists = std::array<std::vector<std::uint32_t>, 8>;
    auto sort_into = [&](std::span<const std::uint32_t> block, ChildLists& children) {
        for (const std::uint32_t prim : block) {
            const Box3f bounds = primitive_bounds(geometry, prim);
            for (std::size_t child = 0; child < 8; ++child) {
                // A primitive whose bounds lie inside the child's box overlaps it: the separating-axis test,
                // whose margin exceeds its rounding, would accept it too, at ten times the cost.
                if (boxes[child].contains(bounds) || (boxes_overlap(bounds, loose[child]) &&
                                                      primitive_overlaps_box(geometry, prim, boxes[child])))
                    children[child].push_back(prim);
            }
        }
    };
    ChildLists children;
    if (references.size() > kSplitBlock) {
        // Fixed blocks, concatenated in block order: the lists stay in increasing order, whatever the
        // threads.
        const std::size_t block_count = (references.size() + kSplitBlock - 1) / kSplitBlock;
        std::vector<ChildLists> blocks(block_count);
        parallel::for_each_index(0, block_count, [&](std::size_t block) {
            sort_into(references.subspan(block * kSplitBlock,
                                         std::min(kSplitBlock, references.size() - block * kSplitBlock)),
                      blocks[block]);
        });
        for (std::size_t child = 0; child < 8; ++child) {
            std::size_t total = 0;
            for (const ChildLists& block : blocks)
                total += block[child].size();
            children[child].reserve(total);
            for (const ChildLists& block : blocks)
                children[child].insert(children[child].end(), block[child].begin(), block[child].end());
        }
        return children;
    }
    sort_into(references, children);
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

namespace {

// The 8 children of `cell`, in child order, with no children or references yet.
std::array<OctreeCell, 8> child_cells(const OctreeCell& cell) {
    std::array<OctreeCell, 8> children{};
    for (std::uint32_t child = 0; child < 8; ++child) {
        children[child].x = static_cast<std::uint16_t>(2u * cell.x + (child & 1u));
        children[child].y = static_cast<std::uint16_t>(2u * cell.y + ((child >> 1) & 1u));
        children[child].z = static_cast<std::uint16_t>(2u * cell.z + ((child >> 2) & 1u));
        children[child].level = static_cast<std::uint8_t>(cell.level + 1);
    }
    return children;
}

// A subtree as the serial depth-first build lays it out: cells[0] is its root, then the root's 8 children,
// then the descendants of child 0, of child 1, ...; leaf references in the same depth-first order. Child
// and reference indices are local to the subtree.
struct Subtree {
    std::vector<OctreeCell> cells;
    std::vector<std::uint32_t> references;
};

class OctreeBuilder {
  public:
    OctreeBuilder(const Geometry& geometry, const Octree& octree, std::size_t leaf_size)
        : geometry_(geometry), octree_(octree), leaf_size_(leaf_size) {}

    // Whether `cell` is split (the stopping rules of build_octree); if so, `children` holds their references.
    [[nodiscard]] bool split(const OctreeCell& cell, std::span<const std::uint32_t> references,
                             std::array<std::vector<std::uint32_t>, 8>& children) const {
        if (cell.level >= octree_.max_depth || references.size() <= leaf_size_) return false;
        children = split_references(geometry_, octree_, cell, references);
        return !split_separates_nothing(children, references.size());
    }

    // Large subtrees: the children are built as subtrees of their own (in parallel with TBB) and spliced in
    // child order, which reproduces the serial layout exactly.
    [[nodiscard]] Subtree build(const OctreeCell& root, std::vector<std::uint32_t> references) const {
        if (references.size() <= kParallelSubtree) return build_serial(root, std::move(references));
        std::array<std::vector<std::uint32_t>, 8> children_references;
        Subtree tree;
        tree.cells.push_back(root);
        if (!split(root, references, children_references)) {
            tree.cells[0].ref_begin = 0;
            tree.cells[0].ref_end = static_cast<std::uint32_t>(references.size());
            tree.references = std::move(references);
            return tree;
        }
        std::vector<std::uint32_t>().swap(references);  // the children hold them now
        std::array<Subtree, 8> children;
        const std::array<OctreeCell, 8> child_roots = child_cells(root);
        auto build_child = [&](std::size_t child) {
            children[child] = build(child_roots[child], std::move(children_references[child]));
        };
        parallel::for_each_index(0, 8, build_child);
        // A child that threw (std::bad_alloc past --max-memory) cancels every task of the build: a nested
        // loop then returns normally with some children not built. Only the outermost call rethrows, so the
        // others leave at once instead of splicing subtrees that do not exist.
        if (parallel::cancelling()) return {};
        tree.cells[0].first_child = 1;
        for (const Subtree& child : children)
            tree.cells.push_back(child.cells[0]);
        for (std::uint32_t child = 0; child < 8; ++child)
            splice(tree, 1 + child, children[child]);
        return tree;
    }

  private:
    // The serial depth-first build, from an explicit stack.
    [[nodiscard]] Subtree build_serial(const OctreeCell& root, std::vector<std::uint32_t> references) const {
        struct Pending {
            std::uint32_t cell;
            std::vector<std::uint32_t> references;
        };
        Subtree tree;
        tree.cells.push_back(root);
        std::vector<Pending> stack;
        stack.push_back({0, std::move(references)});
        std::array<std::vector<std::uint32_t>, 8> children;
        while (!stack.empty()) {
            Pending pending = std::move(stack.back());
            stack.pop_back();
            const OctreeCell cell = tree.cells[pending.cell];
            if (split(cell, pending.references, children)) {
                const auto first_child = static_cast<std::uint32_t>(tree.cells.size());
                tree.cells[pending.cell].first_child = first_child;
                for (const OctreeCell& child : child_cells(cell))
                    tree.cells.push_back(child);
                // Reversed, so that child 0 is built first: depth-first order for cells and references.
                for (std::uint32_t child = 8; child-- > 0;)
                    stack.push_back({first_child + child, std::move(children[child])});
                continue;
            }
            // LEAF
            check_reference_count(tree.references.size() + pending.references.size());
            OctreeCell& leaf = tree.cells[pending.cell];
            leaf.ref_begin = static_cast<std::uint32_t>(tree.references.size());
            tree.references.insert(tree.references.end(), pending.references.begin(),
                                   pending.references.end());
            leaf.ref_end = static_cast<std::uint32_t>(tree.references.size());
        }
        return tree;
    }

    // Appends `child`'s descendants and references to `tree`, whose cell `slot` is child's root.
    static void splice(Subtree& tree, std::uint32_t slot, const Subtree& child) {
        check_reference_count(tree.references.size() + child.references.size());
        // child.cells[i], i >= 1, lands at base + i - 1.
        const auto base = static_cast<std::uint32_t>(tree.cells.size());
        const auto reference_base = static_cast<std::uint32_t>(tree.references.size());
        auto relocated = [&](OctreeCell cell) {
            if (cell.is_leaf()) {
                cell.ref_begin += reference_base;
                cell.ref_end += reference_base;
            } else {
                cell.first_child = base + cell.first_child - 1;
            }
            return cell;
        };
        tree.cells[slot] = relocated(child.cells[0]);
        for (std::size_t i = 1; i < child.cells.size(); ++i)
            tree.cells.push_back(relocated(child.cells[i]));
        tree.references.insert(tree.references.end(), child.references.begin(), child.references.end());
    }

    const Geometry& geometry_;
    const Octree& octree_;
    std::size_t leaf_size_;
};

}  // namespace

int deepest_separating_level(const OctreeCube& cube, float tolerance, int max_depth) {
    int level = 0;
    while (level < max_depth &&
           cube.size * inverse_power_of_two(level + 1) >= kSmallestCellInTolerances * tolerance)
        ++level;
    return level;
}

Octree build_octree(const Geometry& geometry, const OctreeOptions& options) {
    Octree octree;
    const Box3f bounds = geometry.bounds();
    octree.cube = octree_root_cube(bounds);
    octree.tolerance = geometric_tolerance(bounds);
    octree.max_depth = deepest_separating_level(octree.cube, octree.tolerance,
                                                std::clamp(options.max_depth, 0, kOctreeMaxLevel));
    const auto leaf_size = static_cast<std::size_t>(std::max(options.leaf_size, 0));
    if (geometry.size() >= std::numeric_limits<std::uint32_t>::max())
        throw std::length_error("octree: primitive indices must fit 32 bits");
    std::vector<std::uint32_t> all(geometry.size());
    std::iota(all.begin(), all.end(), 0u);
    Subtree tree = OctreeBuilder(geometry, octree, leaf_size).build(OctreeCell{}, std::move(all));
    octree.cells = std::move(tree.cells);
    octree.references = std::move(tree.references);
    return octree;
}

}  // namespace lancer
