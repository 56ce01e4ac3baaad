// The oracle: every ray against every primitive. Every other structure is tested against it.
#pragma once

#include <algorithm>
#include <cstdint>

#include "accel/single_ray.hpp"

namespace lancer {

class BruteAccel final : public SingleRayAccel<BruteAccel> {
  public:
    [[nodiscard]] std::string_view name() const override { return "brute"; }
    [[nodiscard]] AccelStats stats() const override;
    [[nodiscard]] std::size_t memory_bytes() const override { return 0; }

  private:
    friend SingleRayAccel<BruteAccel>;

    void build_from(const Geometry& /*geometry*/, const BuildOptions& /*options*/) {}

    // Every primitive in index order; any hit stops at the first.
    template <bool kAnyHit, bool kCount, class TriangleTestT>
    bool trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counts) const {
        const auto prim_count = static_cast<std::uint32_t>(geometry_.size());
        if constexpr (kAnyHit) {
            std::uint32_t prim = 0;
            while (prim < prim_count && !occludes(geometry_, prim, prepared))
                ++prim;
            if constexpr (kCount) counts.prims_tested += std::min(prim + 1, prim_count);
            return prim < prim_count;
        } else {
            for (std::uint32_t prim = 0; prim < prim_count; ++prim)
                intersect_primitive(geometry_, prim, prepared, best);
            if constexpr (kCount) counts.prims_tested += prim_count;
            return best.hit();
        }
    }
};

extern template class SingleRayAccel<BruteAccel>;

}  // namespace lancer
