// SAH kd-tree (Wald & Havran 2006; seeds 002, 003 section 5.3 and 004): perfect splits over the clipped
// primitive boxes, an O(N log N) event-sweep build (accel/kdtree_build.hpp), and pbrt-v3's stack-based
// front-to-back walk with early exit, its split distances bracketed so that rounding never skips the leaf
// that holds the closest hit (docs/accel/kdtree.md).
#pragma once

#include "accel/kdtree_build.hpp"
#include "lancer/accel.hpp"

namespace lancer {

class KdTreeAccel final : public Accel {
  public:
    [[nodiscard]] std::string_view name() const override { return "kdtree"; }
    [[nodiscard]] AccelStats stats() const override;
    [[nodiscard]] std::size_t memory_bytes() const override;

    // The built tree, for the structural tests.
    [[nodiscard]] const KdTreeData& tree() const { return tree_; }

  private:
    void build_structure(const Geometry& geometry, const BuildOptions& options) override;
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;

    // The walk of one valid ray; kAnyHit returns at the first hit (occlusion).
    template <bool kAnyHit, class PreparedRayT, bool kCount>
    bool walk(const PreparedRayT& prepared, Hit& best, TraversalCounters& counts) const;

    Geometry geometry_;
    BuildOptions options_;
    KdTreeData tree_;
    double build_ms_ = 0.0;
};

}  // namespace lancer
