// The entry point of the BVH builds: the primitives' references, then the builder the options name.
#include "accel/bvh/build.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/build_common.hpp"
#include "core/parallel.hpp"
#include "lancer/huge_pages.hpp"

namespace lancer {
namespace {

// With spatial splits, the references of a build, the parts of cut primitives included, are at most this many
// times the primitives (Embree's split factor): the bound on the build's memory (docs/accel/bvh.md).
constexpr double kReferenceBudget = 1.5;

std::size_t reference_capacity(std::size_t primitives) {
    const auto budget = static_cast<std::size_t>(static_cast<double>(primitives) * kReferenceBudget);
    // Leaf offsets are 32-bit.
    return std::max(primitives, std::min<std::size_t>(budget, std::numeric_limits<std::uint32_t>::max()));
}

// The primitives' references, in storage for `capacity` of them.
BuildRefs make_refs(const Geometry& geometry, std::size_t capacity) {
    BuildRefs refs;
    refs.reserve(capacity);
    refs.resize(geometry.size());
    auto make = [&](std::size_t from, std::size_t to) {
        for (auto prim = static_cast<std::uint32_t>(from); prim < to; ++prim) {
            const Box3f bounds = primitive_bounds(geometry, prim);
            refs[prim] = {bounds, bounds.center(), prim};
        }
    };
    parallel::for_each_chunk(0, refs.size(), 16384, make);
    return refs;
}

}  // namespace

BvhBuildResult build_bvh(const Geometry& geometry, const BvhOptions& options, std::size_t whole_leaf_size) {
    if (geometry.size() == 0) return {};
    whole_leaf_size = std::min<std::size_t>(whole_leaf_size, BvhAccel::kMaxLeafSize);
    const std::size_t primitives = geometry.size();
    const bool spatial_splits = options.spatial_splits && options.builder != BvhBuilder::SweepSah;
    BuildRefs refs = make_refs(geometry, spatial_splits ? reference_capacity(primitives) : primitives);
    if (options.builder == BvhBuilder::SweepSah) return build_sweep_sah(refs, options, whole_leaf_size);
    if (spatial_splits) refs.resize(reference_capacity(primitives));
    return build_binned_sah(refs, primitives, geometry, options, whole_leaf_size);
}

BvhBuildResult build_bvh_over_boxes(std::span<const Box3f> boxes, std::span<const std::uint32_t> ids,
                                    const BvhOptions& options) {
    if (ids.empty()) return {};
    BuildRefs refs(ids.size());
    for (std::size_t i = 0; i < ids.size(); ++i)
        refs[i] = {boxes[ids[i]], boxes[ids[i]].center(), ids[i]};
    BvhOptions without_splits = options;
    without_splits.spatial_splits = false;
    if (options.builder == BvhBuilder::SweepSah) return build_sweep_sah(refs, without_splits, 0);
    return build_binned_sah(refs, refs.size(), Geometry{}, without_splits, 0);
}

double bvh_sah_cost(const HugePageVector<BvhNode>& nodes) {
    if (nodes.empty()) return 0.0;
    const double root_area = nodes[0].bounds().surface_area();
    double weighted_area = 0.0;
    std::size_t references = 0;
    for (const BvhNode& node : nodes) {
        const double area = node.bounds().surface_area();
        weighted_area += node.is_leaf() ? area * node.prim_count * kSahPrimitiveCost : area * kSahNodeCost;
        references += node.prim_count;
    }
    // A tree whose root has no area costs its primitive references.
    return root_area > 0.0 ? weighted_area / root_area : static_cast<double>(references);
}

}  // namespace lancer
