// Binary bounding volume hierarchy built with the surface-area heuristic (MacDonald & Booth 1990; Iehl 2011),
// either by the full sweep over centroids sorted once per axis (Iehl 2011, "incrémental : trier une seule
// fois par axe") or by binning (Wald 2007, "On fast construction of SAH-based bounding volume hierarchies"),
// traversed front to back with a small stack. docs/accel/bvh.md has the design note.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "accel/options.hpp"
#include "accel/single_ray.hpp"
#include "lancer/huge_pages.hpp"

namespace lancer {

enum class BvhBuilder {
    SweepSah,   // Iehl 2011: full sweep over centroids sorted on each axis
    BinnedSah,  // Wald 2007: binned SAH, parallel over oneTBB when available
};

// bvh.leaf_boxes: headers of block boxes in bvh8's leaves of several blocks (BvhOptions::leaf_boxes).
enum class LeafBoxes { Auto, On, Off };
inline constexpr std::size_t kLeafBoxesUpTo = std::size_t{1} << 17;
// bvh.interleaved_streams: several of bvh8_packet's ray streams walking at once (BvhOptions).
enum class InterleavedStreams { Auto, On, Off };
inline constexpr std::size_t kInterleavedStreamsFrom = std::size_t{1} << 21;

// The options of the BVH family (`bvh`, `bvh4`, `bvh8` and their packet structures).
struct BvhOptions {
    static constexpr std::string_view kGroup = "bvh";
    BvhBuilder builder = BvhBuilder::BinnedSah;
    int max_leaf_size = 4;
    // bvh4 and bvh8: a binary subtree of at most this many primitives becomes one leaf of the wide tree,
    // its primitives in consecutive triangle blocks (at least one block's worth is always merged). Larger
    // leaves mean fewer levels of dependent node loads for more triangle tests in lanes; of 8 to 48, 32
    // measured best over the views (docs/accel/bvh_wide.md, "Merged leaves of several blocks"). At most
    // kExactSplitBelow, so that no merged subtree was cut by a spatial split and a leaf holds each
    // primitive once.
    int wide_leaf_size = 32;
    // bvh8: whether leaves of more than one block start with a header of their blocks' boxes, which
    // bvh8_packet's ray streams test before the triangles (bvh_wide.hpp, kLeafHeaderBit). Auto: for
    // bvh8_packet's tree of at most kLeafBoxesUpTo primitives, never for bvh8's own, whose walk steps over
    // them. The header saves triangle tests and costs a fetch; below about 2^17 primitives the leaves stay in
    // the caches and the tests set the time (the bunny's diffuse and shadow views 8-15% faster), above it
    // the fetches do (the dragon's 3-7% slower) (docs/accel/bvh_wide.md, "Block boxes in merged leaves").
    LeafBoxes leaf_boxes = LeafBoxes::Auto;
    // bvh8_packet: whether several ray streams walk at once, a node of each in turn, so that one stream's
    // misses overlap the others' tests. Auto: for trees of at least kInterleavedStreamsFrom primitives. On
    // a tree larger than the caches the streams wait on their loads (the diffuse view 7% faster at 3.5 M
    // triangles, 18% at 14 M); on one that fits, the turns only add work (the dragon's 10% and the bunny's
    // 13% slower) (docs/accel/stream.md, "Streams in flight").
    InterleavedStreams interleaved_streams = InterleavedStreams::Auto;
    int bins = 32;
    // Spatial splits (Stich, Friedrich & Dietrich 2009, the SBVH) in the binned builder: a node may also
    // be split by a plane that cuts references in two, a primitive then appearing in several leaves, within
    // a budget of references (docs/accel/bvh.md, "Spatial splits"). The sweep builder ignores it.
    bool spatial_splits = false;
    // Accel::update refits the tree, and rebuilds it once its SAH cost has grown past this many times the
    // cost it was built with (docs/accel/refit.md, "When to rebuild"). A tree with spatial splits always
    // rebuilds: a refit would widen its split references' clipped boxes to their whole triangles.
    double refit_threshold = 1.5;
};

// 32 bytes, two per cache line (pbrt-v4's LinearBVHNode). Depth-first layout: an inner node's first child
// is the next node, its second child is at `offset`.
struct BvhNode {
    Vec3f lo;                      // 12 bytes
    std::uint32_t offset = 0;      //  4: leaf: first entry of prim_indices; inner: index of the second child
    Vec3f hi;                      // 12
    std::uint16_t prim_count = 0;  // 2: 0 for inner nodes
    std::uint8_t axis = 0;         // 1: split axis of an inner node (the axis its children were sorted on)
    std::uint8_t padding = 0;      // 1

    [[nodiscard]] bool is_leaf() const { return prim_count > 0; }
    [[nodiscard]] Box3f bounds() const { return {lo, hi}; }
};
static_assert(sizeof(BvhNode) == 32);

class BvhAccel final : public SingleRayAccel<BvhAccel> {
  public:
    // The `--set` keys of this structure's option group (accel/options.hpp).
    [[nodiscard]] static std::vector<BuildOptionRow> option_rows();
    [[nodiscard]] std::string_view name() const override { return "bvh"; }
    [[nodiscard]] AccelStats stats() const override;
    [[nodiscard]] std::size_t memory_bytes() const override;
    [[nodiscard]] UpdateMethod update_method() const override;

    // The built hierarchy, for tests and for the structures derived from it (wide BVH, GPU).
    [[nodiscard]] const HugePageVector<BvhNode>& nodes() const { return nodes_; }
    [[nodiscard]] const HugePageVector<std::uint32_t>& prim_indices() const { return prim_indices_; }

    // Leaves never exceed this many primitives, and inner nodes never this depth (the traversal stack size).
    static constexpr int kMaxLeafSize = 64;
    static constexpr int kMaxDepth = 96;

  private:
    friend SingleRayAccel<BvhAccel>;

    void build_from(const Geometry& geometry, const BuildOptions& options);
    UpdateReport update_from(const Geometry& geometry);
    [[nodiscard]] ExportedLayout exported_layout() const override { return {.bvh = this}; }
    // SingleRayAccel's contract.
    template <bool kAnyHit, bool kCount, class TriangleTestT>
    bool trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counts) const;

    HugePageVector<BvhNode> nodes_;
    // Leaf ranges point here; entries are global primitive indices.
    HugePageVector<std::uint32_t> prim_indices_;
    double built_sah_cost_ = 0.0;  // the SAH cost as last built
    double sah_ratio_ = 1.0;       // the present SAH cost over built_sah_cost_
};

extern template class SingleRayAccel<BvhAccel>;

}  // namespace lancer
