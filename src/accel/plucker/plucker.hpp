// The Plücker-connected octree of Portalez & Duguet, "Lancer de rayons dans un octree" (2016):
// the octree of octree_build.hpp made 2:1 balanced (balance.hpp), its leaves linked to their face
// neighbours and laid out as the seed's four arrays (layout.hpp), walked leaf to leaf with Plücker tests
// for the exit face and the sub-face (walk.hpp, conventions.hpp). Design note: docs/accel/plucker.md.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "accel/options.hpp"
#include "accel/plucker/layout.hpp"
#include "lancer/accel.hpp"

namespace lancer {

// The options of `plucker` and `plucker_packet` (Portalez & Duguet 2016): the octree with the 2:1
// rule and face-neighbour links, walked leaf to leaf. max_depth 0 = automatic: round(0.8 log2(N) - 5), the
// depths of the seed's section 5.2 (8 for the bunny's 69k triangles, 10 for the armadillo's 346k, 11 for
// the dragon's 871k). The other fields are the variants of its section 6 (docs/accel/plucker.md).
struct PluckerOptions {
    static constexpr std::string_view kGroup = "plucker";
    int max_depth = 0;
    // Split while a cell holds more references. 32, not the seed's 12 ("6 triangles per leaf on average",
    // 5.1): leaves are tested 8 triangles per block here, so larger leaves cost few extra tests and save
    // steps, memory and build time (docs/accel/plucker.md, "Leaf size"); the seed's tables use 12.
    int leaf_size = 32;
    bool balanced = true;      // false: no 2:1 rule, links to the same-or-larger neighbour and a descent
    bool stored_boxes = true;  // false: cell planes recomputed from integer coordinates and level
    bool morton = false;       // true: cells in depth-first (Morton) order instead of the build's order
};

class PluckerAccel final : public Accel {
  public:
    // The `--set` keys of this structure's option group (accel/options.hpp).
    [[nodiscard]] static std::vector<BuildOptionRow> option_rows();
    [[nodiscard]] std::string_view name() const override { return "plucker"; }
    [[nodiscard]] AccelStats stats() const override { return stats_; }
    [[nodiscard]] std::size_t memory_bytes() const override;

    // A structure read back from a file (serialise.hpp) instead of built: `layout` must have been made on
    // `geometry` (read_plucker_file checks it). options.triangle_test is the only option used.
    void adopt(const Geometry& geometry, const BuildOptions& options, plucker::PluckerLayout layout);

    [[nodiscard]] const plucker::PluckerLayout& layout() const { return layout_; }
    // The depth max_depth = 0 stands for: round(0.8 log2(N) - 5), clamped to [2, kOctreeMaxLevel].
    [[nodiscard]] static int automatic_depth(std::size_t primitive_count);
    // The addresses of the leaf records the walk enters over [tnear, tfar], in order, without testing
    // primitives: the traversal seen from outside, for tests.
    [[nodiscard]] std::vector<std::uint32_t> leaves_along(const Ray& ray) const;

  private:
    void build_structure(const Geometry& geometry, const BuildOptions& options) override;
    // A rebuild: the octree's cells, links and leaf lists all depend on where the triangles are.
    UpdateReport update_structure(const Geometry& geometry) override;
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;

    [[nodiscard]] ExportedLayout exported_layout() const override { return {.plucker = &layout_}; }
    void compute_layout_stats();

    Geometry geometry_;
    BuildOptions options_;
    plucker::PluckerLayout layout_;
    AccelStats stats_;
};

}  // namespace lancer
