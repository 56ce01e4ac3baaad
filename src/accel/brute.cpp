#include "accel/brute.hpp"

#include <algorithm>

#include "accel/primitive_test.hpp"

namespace lancer {

void BruteAccel::build(const Geometry& geometry, const BuildOptions& options) {
    geometry_ = geometry;
    options_ = options;
}

void BruteAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                 TraversalCounters* counters) const {
    dispatch_policies(options_.triangle_test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        const auto prim_count = static_cast<std::uint32_t>(geometry_.size());
        for (std::size_t i = 0; i < rays.size(); ++i) {
            hits[i] = Hit{};
            if (!is_valid(rays[i])) continue;
            const PreparedRay<TriangleTestT> prepared(rays[i]);
            for (std::uint32_t prim = 0; prim < prim_count; ++prim) {
                intersect_primitive(geometry_, prim, prepared, hits[i]);
            }
            if constexpr (kCount) counters->prims_tested += prim_count;
        }
        if constexpr (kCount) counters->rays += rays.size();
    });
}

void BruteAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                TraversalCounters* counters) const {
    dispatch_policies(options_.triangle_test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        const auto prim_count = static_cast<std::uint32_t>(geometry_.size());
        for (std::size_t i = 0; i < rays.size(); ++i) {
            occluded[i] = 0;
            if (!is_valid(rays[i])) continue;
            const PreparedRay<TriangleTestT> prepared(rays[i]);
            std::uint32_t prim = 0;
            while (prim < prim_count && !occludes(geometry_, prim, prepared))
                ++prim;
            occluded[i] = prim < prim_count ? 1 : 0;
            if constexpr (kCount) counters->prims_tested += std::min(prim + 1, prim_count);
        }
        if constexpr (kCount) counters->rays += rays.size();
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
