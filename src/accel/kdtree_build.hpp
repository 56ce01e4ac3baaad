// The SAH kd-tree's node layout and its O(N log N) builder (Wald & Havran 2006, "On building fast kd-trees
// for ray tracing, and on doing that in O(N log N)"), kept apart from the traversal so that the
// tests can read the tree it produces.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/box.hpp"

namespace lancer {

enum class KdTreeCost {
    WaldHavran,  // Wald & Havran 2006: SAH with an empty-space bonus
    Seed003,     // Ferreira & Mendoza 2011, 5.3.2: C = 1 / SA(N) [SA(L)(Nl + Nb) + SA(R)(Nr + Nb)], no bonus
};

// The options of `kdtree` (Wald & Havran 2006). max_depth 0 = automatic: 8 + 1.3 log2(N).
struct KdTreeOptions {
    static constexpr std::string_view kGroup = "kdtree";
    KdTreeCost cost = KdTreeCost::WaldHavran;
    float traversal_cost = 15.0f;
    float intersection_cost = 20.0f;
    // Cost factor (1 - bonus) when a side is empty: Wald & Havran's lambda = 0.8, a 20% bonus. A bonus of 0.8
    // (factor 0.2) spends the depth limit on thin empty slabs: 1.6x the SAH cost and 6x the primitive tests
    // per ray on the armadillo (docs/accel/kdtree.md).
    float empty_bonus = 0.2f;
    int max_depth = 0;
};

// 8 bytes, pbrt-v3's KdAccelNode:
//   payload (4): inner node: the split position (float bits); leaf: its one primitive itself, stored inline,
//                or with 0 or 2+ primitives the offset of its first one in KdTreeData::references
//   bits    (4): low 2 bits: the split axis 0-2, or 3 for a leaf; high 30 bits: inner node: the index of
//                the above child (the below child is the next node); leaf: the primitive count
class KdNode {
  public:
    static constexpr std::uint32_t kLeafTag = 3;
    static constexpr std::uint32_t kMaxField = (std::uint32_t{1} << 30) - 1;  // above index or count

    [[nodiscard]] static KdNode inner(int axis, float split, std::uint32_t above_child) {
        return KdNode(std::bit_cast<std::uint32_t>(split),
                      (above_child << 2) | static_cast<std::uint32_t>(axis));
    }
    // `payload`: the primitive when count == 1, else the offset of the first reference.
    [[nodiscard]] static KdNode leaf(std::uint32_t count, std::uint32_t payload) {
        return KdNode(payload, (count << 2) | kLeafTag);
    }

    [[nodiscard]] bool is_leaf() const { return (bits_ & 3u) == kLeafTag; }
    [[nodiscard]] int axis() const { return static_cast<int>(bits_ & 3u); }
    [[nodiscard]] float split() const { return std::bit_cast<float>(payload_); }
    [[nodiscard]] std::uint32_t above_child() const { return bits_ >> 2; }
    [[nodiscard]] std::uint32_t primitive_count() const { return bits_ >> 2; }
    // A leaf of 0 or 2+ primitives: the offset of its first one in the references.
    [[nodiscard]] std::uint32_t reference_offset() const { return payload_; }
    // The leaf's primitives, inline or in `references`.
    [[nodiscard]] const std::uint32_t* primitives(const std::uint32_t* references) const {
        return primitive_count() == 1 ? &payload_ : references + payload_;
    }

  private:
    KdNode(std::uint32_t payload, std::uint32_t bits) : payload_(payload), bits_(bits) {}

    std::uint32_t payload_;
    std::uint32_t bits_;
};
static_assert(sizeof(KdNode) == 8);

// Deepest tree the builder makes, whatever KdTreeOptions::max_depth asks: the traversal stack is a fixed
// array of this many entries (one push per inner node on the current path).
inline constexpr int kKdTreeMaxDepth = 64;

// What the builder measured, for AccelStats.
struct KdTreeBuildStats {
    std::size_t leaves = 0, empty_leaves = 0, references = 0, max_refs_per_leaf = 0;
    int max_depth = 0;
    double mean_depth = 0.0;          // over all leaves
    double mean_refs_per_leaf = 0.0;  // over the non-empty leaves: empty ones are the SAH's cut-off space
    double sah_cost = 0.0;
};

struct KdTreeData {
    std::vector<KdNode> nodes;  // depth first: the root at 0, a below child right after its parent
    std::vector<std::uint32_t> references;  // primitives of the leaves that hold 2 or more, leaf after leaf
    Box3f bounds;                           // the root's box: the primitives' bounds
    float tolerance = 0.0f;                 // geometric_tolerance(bounds): the walk grows every box by it
    int depth_limit = 0;                    // the max depth the build used (options or 8 + 1.3 log2 N)
    KdTreeBuildStats stats;

    [[nodiscard]] std::span<const std::uint32_t> leaf_primitives(const KdNode& leaf) const {
        return {leaf.primitives(references.data()), leaf.primitive_count()};
    }
};

// The depth limit for N primitives: options.max_depth, or 8 + 1.3 log2 N when it is 0 (pbrt-v3's
// rule), at most kKdTreeMaxDepth. Throws std::invalid_argument for a negative option.
[[nodiscard]] int kdtree_depth_limit(const KdTreeOptions& options, std::size_t primitive_count);

// SAH cost of a split whose children a ray crossing the node enters with probabilities `left_probability`
// and `right_probability` (their surface areas over the node's) and which hold `left_count` and
// `right_count` primitives (the straddling ones in both), in the chosen model:
//   WaldHavran: Ct + Ci (P_L N_L + P_R N_R) (1 - empty_bonus when N_L or N_R is 0);
//   Seed003:    P_L N_L + P_R N_R (Ferreira & Mendoza 2011, 5.3.2: N_L = Trig_left + Trig_both, so N_R).
[[nodiscard]] double kdtree_split_cost(const KdTreeOptions& options, double left_probability,
                                       double right_probability, std::size_t left_count,
                                       std::size_t right_count);
// The cost of making a leaf of `count` primitives instead, in the same model: Ci N (WaldHavran), or N
// (Seed003: the "coût de ne pas diviser" of Ferreira & Mendoza 2011, section 5.3.3, SA(N) N / SA(N)). A node
// is split only when its best split costs strictly less.
[[nodiscard]] double kdtree_leaf_cost(const KdTreeOptions& options, std::size_t count);

// Builds the tree over every primitive of `geometry` (triangles then spheres); with oneTBB, nodes of more
// than 4,096 primitives build their children in parallel, into the same tree whatever the thread count
// (docs/accel/parallel-build.md). Primitives whose bounds are
// empty or NaN are left out: no ray can hit them. Throws std::length_error past 2^30 - 1 primitives or nodes.
[[nodiscard]] KdTreeData build_kdtree(const Geometry& geometry, const KdTreeOptions& options);

}  // namespace lancer
