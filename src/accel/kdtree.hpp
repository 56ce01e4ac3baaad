// SAH kd-tree (Wald & Havran 2006; Iehl 2011; Ferreira & Mendoza 2011, section 5.3; the "Lancer de rayon"
// slides): perfect splits over the clipped primitive boxes, an O(N log N) event-sweep build
// (accel/kdtree_build.hpp), and pbrt-v3's stack-based front-to-back walk with early exit, its split distances
// bracketed so that rounding never skips the leaf that holds the closest hit (docs/accel/kdtree.md).
#pragma once

#include "accel/kdtree_build.hpp"
#include "accel/options.hpp"
#include "accel/single_ray.hpp"

namespace lancer {

class KdTreeAccel final : public SingleRayAccel<KdTreeAccel> {
  public:
    // The `--set` keys of this structure's option group (accel/options.hpp).
    [[nodiscard]] static std::vector<BuildOptionRow> option_rows();
    [[nodiscard]] std::string_view name() const override { return "kdtree"; }
    [[nodiscard]] AccelStats stats() const override;
    [[nodiscard]] std::size_t memory_bytes() const override;

    // The built tree, for the structural tests.
    [[nodiscard]] const KdTreeData& tree() const { return tree_; }

  private:
    friend SingleRayAccel<KdTreeAccel>;

    void build_from(const Geometry& geometry, const BuildOptions& options) {
        tree_ = build_kdtree(geometry, options.group<KdTreeOptions>());
    }
    // The walk of one valid ray (SingleRayAccel's contract).
    template <bool kAnyHit, bool kCount, class TriangleTestT>
    bool trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counts) const;

    KdTreeData tree_;
};

extern template class SingleRayAccel<KdTreeAccel>;

}  // namespace lancer
