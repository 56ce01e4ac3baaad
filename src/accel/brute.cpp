#include "accel/brute.hpp"

#include <algorithm>

#include "accel/primitive_test.hpp"

namespace lancer {

void BruteAccel::build_structure(const Geometry& geometry, const BuildOptions& options) {
    geometry_ = geometry;
    options_ = options;
}

void BruteAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                 TraversalCounters* counters) const {
    const auto prim_count = static_cast<std::uint32_t>(geometry_.size());
    intersect_each(options_.triangle_test, rays, hits, counters,
                   [&]<class TriangleTestT, bool kCount>(const PreparedRay<TriangleTestT>& prepared,
                                                         Hit& best, TraversalCounters& counts) {
                       for (std::uint32_t prim = 0; prim < prim_count; ++prim) {
                           intersect_primitive(geometry_, prim, prepared, best);
                       }
                       if constexpr (kCount) counts.prims_tested += prim_count;
                   });
}

void BruteAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                TraversalCounters* counters) const {
    const auto prim_count = static_cast<std::uint32_t>(geometry_.size());
    occluded_each(options_.triangle_test, rays, occluded, counters,
                  [&]<class TriangleTestT, bool kCount>(const PreparedRay<TriangleTestT>& prepared,
                                                        TraversalCounters& counts) {
                      std::uint32_t prim = 0;
                      while (prim < prim_count && !occludes(geometry_, prim, prepared))
                          ++prim;
                      if constexpr (kCount) counts.prims_tested += std::min(prim + 1, prim_count);
                      return prim < prim_count;
                  });
}

AccelStats BruteAccel::stats() const {
    AccelStats stats;
    stats.primitives = geometry_.size();
    stats.nodes = 1;
    stats.leaves = 1;
    stats.empty_leaves = geometry_.size() == 0 ? 1 : 0;
    stats.references = geometry_.size();
    stats.mean_refs_per_leaf = static_cast<double>(geometry_.size());
    stats.max_refs_per_leaf = geometry_.size();
    return stats;
}

}  // namespace lancer
