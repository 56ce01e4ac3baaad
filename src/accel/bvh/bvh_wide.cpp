#include "accel/bvh/bvh_wide.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <stdexcept>

#include "accel/build_util.hpp"
#include "accel/bvh/build.hpp"
#include "accel/bvh/bvh_wide_walk.hpp"
#include "accel/bvh/collapse.hpp"
#include "accel/bvh/refit.hpp"
#include "accel/bvh/small_subtree.hpp"
#include "accel/primitive_intersect.hpp"
#include "core/parallel.hpp"
#include "lancer/huge_pages.hpp"

namespace lancer {
namespace {

// The primitives under a binary node: the range [first, first + count) of prim_indices (depth first layout)
// and whether the collapse keeps the whole subtree as one leaf: a binary leaf, or a subtree of at most
// `merge_limit` primitives (bvh.wide_leaf_size), whose blocks a ray tests side by side instead of walking
// its nodes one load after another. Such a subtree never holds a primitive twice: spatial splits, which put
// one primitive in several leaves, cut only nodes of more than kExactSplitBelow references
// (docs/accel/bvh.md, "Spatial splits"; WideBvh.LeavesHoldEachPrimitiveOnce).
struct SubtreeRange {
    std::uint32_t first = 0, count = 0;
    bool as_leaf = false;
};

// Children follow their parent in the depth-first array, so one backward pass sees them first.
HugePageVector<SubtreeRange> subtree_ranges(const HugePageVector<BvhNode>& binary,
                                            std::uint32_t merge_limit) {
    HugePageVector<SubtreeRange> ranges(binary.size());
    for (std::size_t i = binary.size(); i-- > 0;) {
        const BvhNode& node = binary[i];
        if (node.is_leaf()) {
            ranges[i] = {node.offset, node.prim_count, true};
            continue;
        }
        const SubtreeRange& left = ranges[i + 1];
        const SubtreeRange& right = ranges[node.offset];
        const std::uint32_t count = left.count + right.count;
        ranges[i] = {left.first, count, count <= merge_limit && right.first == left.first + left.count};
    }
    return ranges;
}

struct CollapseInput {
    const HugePageVector<BvhNode>& binary;
    const HugePageVector<SubtreeRange>& ranges;
    bool leaf_boxes;  // leaves of more than one block get a header (bvh.leaf_boxes)
};

// A leaf of the wide tree: the primitives prim_indices[first, first + count), in the blocks its slot's child
// index `child` gives (leaf_span; its header first, if it has one). The collapse only numbers the blocks;
// they are written afterwards, in parallel.
struct LeafBlocks {
    std::uint32_t child = 0, first = 0, count = 0;
};

// Collapses the binary subtree under `binary_root` (an inner node, or the root leaf of a tiny scene) into
// wide nodes appended depth first to `wide`, and returns the index of the first; each node's children by
// collapse_children (Dammertz et al. 2008). Subtrees of at most bvh.wide_leaf_size primitives count as
// leaves (SubtreeRange); a leaf's blocks are numbered from `blocks_used` on, in this depth-first order, and
// listed in `leaves`.
template <int W>
std::uint32_t collapse(const CollapseInput& input, std::uint32_t binary_root,
                       HugePageVector<WideBvhNode<W>>& wide, HugePageVector<LeafBlocks>& leaves,
                       std::uint32_t& blocks_used) {
    const HugePageVector<BvhNode>& binary = input.binary;
    std::array<std::uint32_t, W> children{};
    const int child_count = collapse_children<W>(
        binary, binary_root, [&](std::uint32_t i) { return input.ranges[i].as_leaf; }, children);

    const auto index = static_cast<std::uint32_t>(wide.size());
    wide.emplace_back();
    for (int slot = 0; slot < child_count; ++slot) {
        const BvhNode& child = binary[children[slot]];
        for (int axis = 0; axis < 3; ++axis) {
            wide[index].bounds[WideBvhNode<W>::kLo][axis][slot] = child.lo[axis];
            wide[index].bounds[WideBvhNode<W>::kHi][axis][slot] = child.hi[axis];
        }
        const SubtreeRange& range = input.ranges[children[slot]];
        if (range.as_leaf) {
            const std::uint32_t blocks = block_count(range.count, WideBvhAccel<W>::kBlockLanes);
            const bool header = input.leaf_boxes && blocks > 1;
            // The top bit marks a header (kLeafHeaderBit): 2^31 blocks, 687 GB, are past any machine here.
            if (blocks_used >= kLeafHeaderBit - blocks - 1)
                throw std::length_error("bvh4/bvh8: more than 2^31 triangle blocks");
            const std::uint32_t leaf_child = blocks_used | (header ? kLeafHeaderBit : 0u);
            wide[index].child[slot] = leaf_child;
            wide[index].prim_count[slot] = range.count;
            leaves.push_back({leaf_child, range.first, range.count});
            blocks_used += blocks + (header ? 1 : 0);
        } else {
            // Indexed, not referenced: the recursion appends to `wide`.
            const std::uint32_t child_index = collapse<W>(input, children[slot], wide, leaves, blocks_used);
            wide[index].child[slot] = child_index;
        }
    }
    return index;
}

}  // namespace

void write_leaf_boxes(const Geometry& geometry, const TriangleBlock<8>* blocks, std::uint32_t count,
                      float margin, TriangleBlock<8>& header) {
    constexpr int kLanes = 8;
    static_assert(block_count(BvhAccel::kMaxLeafSize, kLanes) <= kLanes,
                  "a header has a lane for each block");
    for (int lane = 0; lane < kLanes; ++lane) {
        Box3f box;  // empty: inverted, never hit
        if (static_cast<std::uint32_t>(lane) < count) {
            for (const std::uint32_t prim : blocks[lane].prim) {
                if (prim != TriangleBlock<kLanes>::kNoPrimitive) box.extend(primitive_bounds(geometry, prim));
            }
            box = box.grown(margin);
        }
        for (int axis = 0; axis < 3; ++axis) {
            header.vertex[WideBvhNode<8>::kLo][axis][lane] = box.lo[axis];
            header.vertex[WideBvhNode<8>::kHi][axis][lane] = box.hi[axis];
            header.vertex[2][axis][lane] = std::numeric_limits<float>::quiet_NaN();
        }
        header.prim[lane] = TriangleBlock<kLanes>::kNoPrimitive;
    }
}

template <int W>
void WideBvhAccel<W>::build_from(const Geometry& geometry, const BuildOptions& options) {
    // Subtrees of at most one block become leaves whole (SubtreeRange): the binary build leaves them unsplit.
    // Larger ones, up to bvh.wide_leaf_size, are built as binary subtrees and merged here into one leaf.
    const BvhOptions& bvh_options = options.group<BvhOptions>();
    BvhBuildResult binary = build_bvh(geometry, bvh_options, kBlockLanes);
    nodes_.clear();
    blocks_.clear();
    if (!binary.nodes.empty()) {
        // Clamped as the binary leaf size is (build_common.hpp): options set in code skip the registry's
        // range, and a leaf past kExactSplitBelow could hold a spatial split's duplicates and overflow the
        // packet kernel's per-leaf arrays.
        static_assert(kBlockLanes <= static_cast<int>(kExactSplitBelow));
        const auto merge_limit = static_cast<std::uint32_t>(
            std::clamp(bvh_options.wide_leaf_size, kBlockLanes, static_cast<int>(kExactSplitBelow)));
        const HugePageVector<SubtreeRange> ranges = subtree_ranges(binary.nodes, merge_limit);
        // Each wide node but a tiny scene's root is rooted at a binary node that is no leaf of the wide
        // tree, and each wide leaf at one that is: storage for that many is never moved.
        const auto roots = static_cast<std::size_t>(std::count_if(
            ranges.begin(), ranges.end(), [](const SubtreeRange& range) { return !range.as_leaf; }));
        nodes_.reserve(std::max<std::size_t>(roots, 1));
        HugePageVector<LeafBlocks> leaves;
        leaves.reserve(ranges.size() - roots);
        std::uint32_t blocks_used = 0;
        // Auto is off here: bvh8's own walk steps over the headers; bvh8_packet asks for them
        // (bvh8_packet.cpp).
        const bool leaf_boxes = kLeafBoxes<W> && bvh_options.leaf_boxes == LeafBoxes::On;
        collapse<W>({binary.nodes, ranges, leaf_boxes}, 0, nodes_, leaves, blocks_used);
        blocks_.reserve(blocks_used);
        blocks_.resize(blocks_used);
        // The leaves' blocks, disjoint and numbered already: the same bytes whatever the thread count. The
        // headers' margin is the refit's, so that a refit to this geometry writes the same bytes.
        const float margin = refit_margin(geometry, this->built_bounds());
        parallel::for_each_chunk(0, leaves.size(), 1024, [&](std::size_t from, std::size_t to) {
            for (std::size_t i = from; i < to; ++i) {
                const LeafBlocks& leaf = leaves[i];
                const LeafSpan span = leaf_span<W>(leaf.child, leaf.count);
                write_leaf_blocks(geometry, std::span(binary.prim_indices).subspan(leaf.first, leaf.count),
                                  blocks_.data() + span.first);
                if constexpr (kLeafBoxes<W>) {
                    if (has_leaf_boxes(leaf.child)) {
                        write_leaf_boxes(geometry, blocks_.data() + span.first, span.end - span.first, margin,
                                         blocks_[leaf_start(leaf.child)]);
                    }
                }
            }
        });
    }
    built_sah_cost_ = wide_bvh_sah_cost<W>(nodes_);
    sah_ratio_ = 1.0;
}

template <int W>
UpdateMethod WideBvhAccel<W>::update_method() const {
    return options_.template group<BvhOptions>().spatial_splits ? UpdateMethod::Rebuild : UpdateMethod::Refit;
}

template <int W>
UpdateReport WideBvhAccel<W>::update_from(const Geometry& geometry) {
    using Base = SingleRayAccel<WideBvhAccel<W>>;
    if (update_method() == UpdateMethod::Rebuild) return Base::update_from(geometry);
    geometry_ = geometry;
    sah_ratio_ = refit_sah_ratio(
        refit_wide_bvh(geometry, nodes_, blocks_, refit_margin(geometry, this->built_bounds())),
        built_sah_cost_);
    if (sah_ratio_ > options_.template group<BvhOptions>().refit_threshold)
        return Base::update_from(geometry);
    return {.method = UpdateMethod::Refit, .sah_ratio = sah_ratio_};
}

template <int W>
template <bool kAnyHit, bool kCount, class TriangleTestT>
bool WideBvhAccel<W>::trace(const PreparedRay<TriangleTestT>& prepared, Hit& best,
                            TraversalCounters& counts) const {
    return wide_walk::traverse<W, kAnyHit, kCount>(nodes_, blocks_, geometry_, prepared, best, counts);
}

template <int W>
AccelStats WideBvhAccel<W>::stats() const {
    AccelStats stats;
    stats.build_ms = build_ms_;
    stats.primitives = geometry_.size();
    TreeShape shape;
    std::size_t headers = 0;
    // Depths and counts in one walk; leaves live in their parents' slots, at the parent's depth + 1.
    double depth_sum = 0.0;
    std::vector<std::pair<std::uint32_t, int>> pending;
    if (!nodes_.empty()) pending.push_back({0, 0});
    while (!pending.empty()) {
        const auto [index, depth] = pending.back();
        pending.pop_back();
        const WideBvhNode<W>& node = nodes_[index];
        for (int slot = 0; slot < W; ++slot) {
            if (node.is_empty(slot)) continue;
            if (node.prim_count[slot] == 0) {
                pending.push_back({node.child[slot], depth + 1});
                continue;
            }
            ++shape.leaves;
            headers += has_leaf_boxes(node.child[slot]) ? 1 : 0;
            shape.references += node.prim_count[slot];
            depth_sum += depth + 1;
            shape.max_depth = std::max(shape.max_depth, depth + 1);
            shape.max_refs_per_leaf = std::max<std::size_t>(shape.max_refs_per_leaf, node.prim_count[slot]);
        }
    }
    shape.nodes = nodes_.size() + shape.leaves;
    stats.memory_by_array = {{"nodes", nodes_.size() * sizeof(WideBvhNode<W>)},
                             {"blocks", (blocks_.size() - headers) * sizeof(Block)}};
    if constexpr (kLeafBoxes<W>) stats.memory_by_array.push_back({"leaf boxes", headers * sizeof(Block)});
    stats.figures = bvh_figures(shape, depth_sum, wide_bvh_sah_cost<W>(nodes_), sah_ratio_);
    return stats;
}

template <int W>
std::size_t WideBvhAccel<W>::memory_bytes() const {
    return nodes_.size() * sizeof(WideBvhNode<W>) + blocks_.size() * sizeof(Block);
}

template class SingleRayAccel<WideBvhAccel<4>>;
template class SingleRayAccel<WideBvhAccel<8>>;
template class WideBvhAccel<4>;
template class WideBvhAccel<8>;

}  // namespace lancer
