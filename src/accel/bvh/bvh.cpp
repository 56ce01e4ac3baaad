#include "accel/bvh/bvh.hpp"

#include <array>

#include "accel/bvh/build.hpp"
#include "accel/bvh/refit.hpp"
#include "accel/bvh/small_subtree.hpp"
#include "accel/primitive_intersect.hpp"

namespace lancer {

void BvhAccel::build_from(const Geometry& geometry, const BuildOptions& options) {
    BvhBuildResult built = build_bvh(geometry, options.group<BvhOptions>());
    nodes_ = std::move(built.nodes);
    prim_indices_ = std::move(built.prim_indices);
    built_sah_cost_ = bvh_sah_cost(nodes_);
    sah_ratio_ = 1.0;
}

UpdateMethod BvhAccel::update_method() const {
    return options_.group<BvhOptions>().spatial_splits ? UpdateMethod::Rebuild : UpdateMethod::Refit;
}

UpdateReport BvhAccel::update_from(const Geometry& geometry) {
    if (update_method() == UpdateMethod::Rebuild) return SingleRayAccel::update_from(geometry);
    geometry_ = geometry;
    sah_ratio_ = refit_sah_ratio(
        refit_bvh(geometry, prim_indices_, nodes_, refit_margin(geometry, built_bounds())), built_sah_cost_);
    if (sah_ratio_ > options_.group<BvhOptions>().refit_threshold)
        return SingleRayAccel::update_from(geometry);
    return {.method = UpdateMethod::Refit, .sah_ratio = sah_ratio_};
}

namespace {

struct StackEntry {
    std::uint32_t node;
    float t_entry;  // where the ray enters the node's box: the node is skipped once a hit is closer
};

// Front-to-back traversal shared by closest hit (kAnyHit false) and occlusion (kAnyHit true). At an inner
// node both children's boxes are tested; the nearer child is visited first and the farther one pushed with
// its entry distance, so that a popped node is skipped when the closest hit so far lies before it.
template <bool kAnyHit, bool kCount, class TriangleTestT>
bool traverse(const HugePageVector<BvhNode>& nodes, const HugePageVector<std::uint32_t>& prim_indices,
              const Geometry& geometry, const PreparedRay<TriangleTestT>& prepared, Hit& best,
              TraversalCounters& counters) {
    if (nodes.empty()) return false;
    const Ray& ray = prepared.ray;
    const SlabRay slab(ray);
    std::array<StackEntry, BvhAccel::kMaxDepth + 1> stack;
    int stack_size = 0;
    float t_entry, t_exit;
    if (!intersect_box(slab, nodes[0].bounds(), ray.tnear, ray.tfar, t_entry, t_exit)) return false;
    std::uint32_t current = 0;
    while (true) {
        const BvhNode& node = nodes[current];
        if constexpr (kCount) ++counters.nodes_visited;
        if (node.is_leaf()) {
            if constexpr (kCount) counters.prims_tested += node.prim_count;
            for (std::uint32_t i = node.offset; i < node.offset + node.prim_count; ++i) {
                if constexpr (kAnyHit) {
                    if (occludes(geometry, prim_indices[i], prepared)) return true;
                } else {
                    intersect_primitive(geometry, prim_indices[i], prepared, best);
                }
            }
        } else {
            const float t_limit = best.hit() ? best.t : ray.tfar;
            const std::uint32_t first = current + 1, second = node.offset;
            float first_entry, second_entry;
            const bool hit_first =
                intersect_box(slab, nodes[first].bounds(), ray.tnear, t_limit, first_entry, t_exit);
            const bool hit_second =
                intersect_box(slab, nodes[second].bounds(), ray.tnear, t_limit, second_entry, t_exit);
            if (hit_first && hit_second) {
                const bool first_is_near = first_entry <= second_entry;
                stack[static_cast<std::size_t>(stack_size++)] =
                    first_is_near ? StackEntry{second, second_entry} : StackEntry{first, first_entry};
                current = first_is_near ? first : second;
                continue;
            }
            if (hit_first || hit_second) {
                current = hit_first ? first : second;
                continue;
            }
        }
        // Pop the next node that may still hold a hit no farther than the best one.
        do {
            if (stack_size == 0) return best.hit();
            const StackEntry entry = stack[static_cast<std::size_t>(--stack_size)];
            current = entry.node;
            if (!best.hit() || entry.t_entry <= best.t) break;
        } while (true);
    }
}

}  // namespace

template <bool kAnyHit, bool kCount, class TriangleTestT>
bool BvhAccel::trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counts) const {
    return traverse<kAnyHit, kCount>(nodes_, prim_indices_, geometry_, prepared, best, counts);
}

template class SingleRayAccel<BvhAccel>;

AccelStats BvhAccel::stats() const {
    AccelStats stats;
    stats.build_ms = build_ms_;
    stats.primitives = geometry_.size();
    TreeShape shape{.nodes = nodes_.size(), .references = prim_indices_.size()};
    // Leaf depths by walking the depth-first layout with an explicit stack.
    std::vector<std::pair<std::uint32_t, int>> pending;
    if (!nodes_.empty()) pending.push_back({0, 0});
    double depth_sum = 0.0;
    while (!pending.empty()) {
        const auto [index, depth] = pending.back();
        pending.pop_back();
        const BvhNode& node = nodes_[index];
        if (node.is_leaf()) {
            ++shape.leaves;
            depth_sum += depth;
            shape.max_depth = std::max(shape.max_depth, depth);
            shape.max_refs_per_leaf = std::max<std::size_t>(shape.max_refs_per_leaf, node.prim_count);
        } else {
            pending.push_back({node.offset, depth + 1});
            pending.push_back({index + 1, depth + 1});
        }
    }
    stats.figures = bvh_figures(shape, depth_sum, bvh_sah_cost(nodes_), sah_ratio_);
    stats.memory_by_array = {{"nodes", nodes_.size() * sizeof(BvhNode)},
                             {"prim_indices", prim_indices_.size() * sizeof(std::uint32_t)}};
    return stats;
}

std::size_t BvhAccel::memory_bytes() const {
    return nodes_.size() * sizeof(BvhNode) + prim_indices_.size() * sizeof(std::uint32_t);
}

std::vector<BuildOptionRow> BvhAccel::option_rows() {
    return {
        choice_option<BvhOptions, BvhBuilder>(
            "builder", "the SAH builder: binned, or a full sweep (Iehl 2011)", &BvhOptions::builder,
            {{"binned", BvhBuilder::BinnedSah}, {"sweep", BvhBuilder::SweepSah}}),
        number_option("max_leaf_size", "primitives a leaf may hold (also bvh4, bvh8)",
                      &BvhOptions::max_leaf_size, 1, 64),
        number_option("wide_leaf_size",
                      "primitives a binary subtree may hold to become one leaf of bvh4 or bvh8 (at least a "
                      "block's lanes)",
                      &BvhOptions::wide_leaf_size, 1, static_cast<int>(kExactSplitBelow)),
        choice_option<BvhOptions, LeafBoxes>(
            "leaf_boxes",
            "bvh8's leaves of several blocks start with their blocks' boxes, which bvh8_packet's ray streams "
            "test first: auto (bvh8_packet's tree up to 131072 primitives), on or off",
            &BvhOptions::leaf_boxes,
            {{"auto", LeafBoxes::Auto}, {"on", LeafBoxes::On}, {"off", LeafBoxes::Off}}),
        choice_option<BvhOptions, InterleavedStreams>(
            "interleaved_streams",
            "bvh8_packet's ray streams walk several at once, a node of each in turn: auto (trees of 2097152 "
            "primitives or more), on or off",
            &BvhOptions::interleaved_streams,
            {{"auto", InterleavedStreams::Auto},
             {"on", InterleavedStreams::On},
             {"off", InterleavedStreams::Off}}),
        number_option("bins", "bins of the binned builder", &BvhOptions::bins, 2, 256),
        flag_option("spatial_splits", "spatial splits in the binned builder (the SBVH)",
                    &BvhOptions::spatial_splits),
        number_option("refit_threshold",
                      "an update rebuilds once the refitted tree's SAH cost passes this many times its cost "
                      "as built",
                      &BvhOptions::refit_threshold, 1.0, 1e9)};
}

}  // namespace lancer
