// The binned SAH builder (binned_builder.cpp), with its spatial splits (spatial_splits.cpp); subtrees of a
// few references it hands to SmallSubtree (small_subtree.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>

#include "accel/bvh/build_common.hpp"
#include "accel/bvh/node_slots.hpp"
#include "lancer/huge_pages.hpp"

namespace lancer {

// A node's references refs[begin, end), and the free positions [end, capacity_end) that spatial splits in
// its subtree may fill with the second parts of the references they cut (Embree's extended ranges). Without
// spatial splits there are none: capacity_end == end.
struct RefRange {
    std::size_t begin = 0, end = 0, capacity_end = 0;

    [[nodiscard]] std::size_t size() const { return end - begin; }
    [[nodiscard]] std::size_t free() const { return capacity_end - end; }
    [[nodiscard]] std::size_t capacity() const { return capacity_end - begin; }
};

// The children's ranges for `left_count` then `right_count` references out of a node whose range is
// `range`: the free positions are shared in proportion to the references (Embree's setExtentedRanges), so
// that a child has room for spatial splits in proportion to its size.
[[nodiscard]] inline std::pair<RefRange, RefRange> share_free_positions(const RefRange& range,
                                                                        std::size_t left_count,
                                                                        std::size_t right_count) {
    const std::size_t free = range.capacity() - left_count - right_count;
    const auto left_free =
        std::min(free, static_cast<std::size_t>(static_cast<double>(free) * static_cast<double>(left_count) /
                                                static_cast<double>(left_count + right_count)));
    const std::size_t right_begin = range.begin + left_count + left_free;
    return {{range.begin, range.begin + left_count, right_begin},
            {right_begin, right_begin + right_count, range.capacity_end}};
}

// Binned SAH (Wald 2007): centroids are binned on each axis, only bin boundaries are candidates. Large nodes
// bin in parallel and large subtrees build in parallel; bin merges are exact (integer counts, min/max of
// boxes), so the result does not depend on the thread count.
//
// With spatial splits (Stich, Friedrich & Dietrich, "Spatial Splits in Bounding Volume Hierarchies", HPG
// 2009), a node whose best object split leaves overlapping children also bins its references between planes
// of its own box, each reference clipped to every bin it crosses, and may split at a plane that cuts
// references in two. The second parts go to the node's free positions, which every split shares between
// its children in proportion to their references; the whole array, hence the number of references, is
// bounded by kReferenceBudget primitives (docs/accel/bvh.md, "Spatial splits").
class BinnedBuilder {
  public:
    // A node's reference boxes' bounds and its centroids' bounds.
    using NodeBounds = std::pair<Box3f, Box3f>;

    // refs[0, primitives) are the primitives' references; the rest of `refs` is free for spatial splits.
    // Nodes of at most `whole_leaf_size` references are leaves (build_bvh).
    BinnedBuilder(BuildRefs& refs, const Geometry& geometry, const BvhOptions& options,
                  std::size_t whole_leaf_size);

    void build(NodeSlots& slots, std::size_t primitives);

    // After build: the primitive of the reference at `position`, which a leaf holds.
    [[nodiscard]] std::uint32_t leaf_primitive(std::size_t position) const { return per_position_[position]; }

    // Nodes of more references bin them in parallel.
    static constexpr std::size_t kParallelBinning = 65536;
    // References per task of the parallel binning.
    static constexpr std::size_t kBinningChunk = 16384;

  private:
    static constexpr int kMaxBins = 256;
    static constexpr std::size_t kParallelSubtree = 4096;
    // Stich et al.'s alpha ("restricting spatial split attempts"): a spatial split is tried only where the
    // object split's children overlap by more than this share of the root's area, and by at least this share
    // of the node's own area (Embree's HIGH builder asks for both).
    static constexpr float kMinOverlap = 1e-5f;
    static constexpr float kMinNodeOverlap = 0.1f;

    // A node's bins on each axis, and the bin of a centroid (binned_builder.cpp).
    struct Bins;
    struct BinMap;

    // An object split and its children's boxes: the union of each side's bins, whose overlap decides whether
    // a spatial split is tried, and which its children take as their bounds.
    struct ObjectSplit {
        Split split;
        Box3f left_bounds, right_bounds;
    };

    // A spatial split: the plane on `split.axis` at boundary `split.bin` of the node's spatial bins, and the
    // children as binning saw them, which reference unsplitting weighs each cut reference against.
    struct SpatialSplit {
        Split split;
        float plane = 0.0f;
        Box3f left_bounds, right_bounds;
        std::uint32_t left_count = 0, right_count = 0;
    };

    struct Children {
        int axis = -1;
        RefRange left, right;
        NodeBounds left_bounds, right_bounds;
    };

    // The node over refs_[range.begin, range.end), whose reference boxes and centroids `node` bounds.
    void build(NodeSlots& slots, std::size_t slot, const RefRange& range, int depth, const NodeBounds& node);

    // A leaf over refs_[range.begin, range.end), its primitives recorded for leaf_primitive.
    void set_leaf(NodeSlots& slots, std::size_t slot, const Box3f& bounds, const RefRange& range);
    void record_leaf_primitives(std::size_t begin, std::size_t end);
    [[nodiscard]] NodeBounds bounds_of(std::size_t begin, std::size_t end) const;
    void bin(std::size_t begin, std::size_t end, const BinMap& map, Bins& bins) const;
    [[nodiscard]] ObjectSplit best_split(std::size_t begin, std::size_t end, const BinMap& map,
                                         const Box3f& centroids) const;
    // The left child's end and both children's centroid bounds.
    std::tuple<std::size_t, Box3f, Box3f> partition(std::size_t begin, std::size_t end, const BinMap& map,
                                                    const Split& split);
    Children object_partition(const RefRange& range, const ObjectSplit& object, const BinMap& map,
                              const Box3f& centroids);

    // Spatial splits (spatial_splits.cpp).
    [[nodiscard]] bool worth_a_spatial_split(const RefRange& range, const Box3f& bounds,
                                             const ObjectSplit& object) const;
    [[nodiscard]] SpatialSplit best_spatial_split(const RefRange& range, const Box3f& bounds) const;
    std::optional<Children> spatial_partition(const RefRange& range, const Box3f& bounds,
                                              const SpatialSplit& spatial);

    BuildRefs& refs_;
    const Geometry& geometry_;
    int max_leaf_;
    std::size_t whole_leaf_size_;
    int bins_;
    bool spatial_splits_;
    float min_overlap_area_ = 0.0f;
    // One entry per reference position: pair_partition's scratch while the position's node is split (a
    // node's partition uses its own range), then, once a leaf holds the position, its reference's primitive,
    // which compact() reads instead of the 40-byte references (the positions of no leaf are never read).
    HugePageBuffer<std::uint32_t> per_position_;
};

}  // namespace lancer
