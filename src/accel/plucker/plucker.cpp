#include "accel/plucker/plucker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "accel/plucker/balance.hpp"
#include "accel/plucker/build.hpp"
#include "accel/plucker/leaf_block.hpp"
#include "accel/plucker/walk.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/tree_shape.hpp"

namespace lancer {

using plucker::PluckerLayout;

int PluckerAccel::automatic_depth(std::size_t primitive_count) {
    const double log_count = std::log2(static_cast<double>(std::max<std::size_t>(primitive_count, 1)));
    return std::clamp(static_cast<int>(std::lround(0.8 * log_count - 5.0)), 2, kOctreeMaxLevel);
}

void PluckerAccel::build_structure(const Geometry& geometry, const BuildOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    geometry_ = geometry;
    options_ = options;
    const PluckerOptions& plucker_options = options.group<PluckerOptions>();
    OctreeOptions octree_options;
    octree_options.max_depth =
        plucker_options.max_depth > 0 ? plucker_options.max_depth : automatic_depth(geometry.size());
    octree_options.leaf_size = plucker_options.leaf_size;
    Octree octree = build_octree(geometry, octree_options);
    if (plucker_options.balanced) plucker::balance_octree(geometry, octree);
    layout_ = plucker::layout_octree(
        geometry, octree, {plucker_options.stored_boxes, plucker_options.balanced, plucker_options.morton});
    const auto stop = std::chrono::steady_clock::now();
    compute_layout_stats();
    stats_.build_ms = std::chrono::duration<double, std::milli>(stop - start).count();
}

UpdateReport PluckerAccel::update_structure(const Geometry& geometry) {
    // A structure read from a file rebuilds with the options it was written with (adopt keeps them).
    const BuildOptions options = options_;
    build_structure(geometry, options);
    return {};
}

void PluckerAccel::adopt(const Geometry& geometry, const BuildOptions& options, PluckerLayout layout) {
    accept_geometry(geometry);
    // The layout was built on the geometry at the scale the structures see it (read_plucker_file checks it).
    geometry_ = built_geometry();
    options_ = options;
    PluckerOptions& plucker_options = options_.group<PluckerOptions>();
    plucker_options.balanced = layout.options.balanced;
    plucker_options.stored_boxes = layout.options.stored_boxes;
    plucker_options.morton = layout.options.morton;
    layout_ = std::move(layout);
    compute_layout_stats();
}

// The statistics of the tree, read back from `locate` and the leaf records.
void PluckerAccel::compute_layout_stats() {
    stats_ = AccelStats{};
    stats_.primitives = geometry_.size();
    TreeShape shape{.nodes = layout_.locate.size(), .references = layout_.primitives.size()};
    double sah_cost = 0.0;
    std::vector<std::uint8_t> level(layout_.locate.size(), 0);
    std::size_t depth_sum = 0, non_empty = 0;
    for (std::size_t index = 0; index < layout_.locate.size(); ++index) {
        const std::uint32_t word = layout_.locate[index];
        if (word & 1u) {
            for (std::uint32_t child = 0; child < 8; ++child)
                level[(word >> 1) + child] = static_cast<std::uint8_t>(level[index] + 1);
            sah_cost += std::ldexp(1.0, -2 * level[index]);
            continue;
        }
        const std::uint32_t count = layout_.cells[(word >> 1) + plucker::kTriangleCount];
        ++shape.leaves;
        depth_sum += level[index];
        shape.max_depth = std::max<int>(shape.max_depth, level[index]);
        shape.max_refs_per_leaf = std::max<std::size_t>(shape.max_refs_per_leaf, count);
        sah_cost += std::ldexp(1.0, -2 * level[index]) * count;
        if (count == 0)
            ++shape.empty_leaves;
        else
            ++non_empty;
    }
    shape.mean_depth =
        shape.leaves == 0 ? 0.0 : static_cast<double>(depth_sum) / static_cast<double>(shape.leaves);
    shape.mean_refs_per_leaf =
        non_empty == 0 ? 0.0 : static_cast<double>(shape.references) / static_cast<double>(non_empty);
    stats_.figures = tree_figures(shape);
    stats_.figures.push_back(
        value_figure("sah_cost", sah_cost,
                     "unit costs, as the octree's: inner cells' areas plus leaves' areas "
                     "times their triangles, over the root's"));
    // The seed's four arrays (Table 3), then the point-location tree this implementation adds.
    stats_.memory_by_array = {
        {"cube map", layout_.cube_map.texels.size() * sizeof(std::uint32_t)},
        {"octree", layout_.cells.size() * sizeof(std::uint32_t)},
        {"triangles", layout_.primitives.size() * sizeof(plucker::PluckerPrimitive)},
        {"boxes", layout_.boxes.size() * sizeof(plucker::PluckerBox)},
        {"locate", layout_.locate.size() * sizeof(std::uint32_t)},
    };
}

std::size_t PluckerAccel::memory_bytes() const {
    std::size_t bytes = 0;
    for (const auto& [array, size] : stats_.memory_by_array)
        bytes += size;
    return bytes;
}

void PluckerAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                   TraversalCounters* counters) const {
    const plucker::PluckerView view = plucker::view_of(layout_);
    dispatch_policies(options_.triangle_test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters local;  // summed here, so that the hot loop does not write through the pointer
        plucker::dispatch_layout(layout_.options, [&]<bool kBalanced, bool kStoredBoxes>() {
            plucker::CellCounter<kCount> steps{local};
            for (std::size_t i = 0; i < rays.size(); ++i) {
                Hit best;
                if (is_valid(rays[i])) {
                    const PreparedRay<TriangleTestT> prepared(rays[i]);
                    const auto block_ray = plucker::leaf_block_ray(prepared, geometry_);
                    const Ray& ray = prepared.ray;
                    plucker::walk<kBalanced, kStoredBoxes>(
                        view, plucker::kTables, ray,
                        [&](const std::uint32_t* record, float) {
                            plucker::for_each_leaf_block(
                                layout_, record, [&](const plucker::LeafBlock& block) {
                                    intersect_block(geometry_, block, block_ray, best);
                                    return false;
                                });
                            if constexpr (kCount) local.prims_tested += record[plucker::kTriangleCount];
                            return best.hit() ? best.t : ray.tfar;
                        },
                        steps);
                }
                hits[i] = best;
            }
        });
        if constexpr (kCount) {
            local.rays = rays.size();
            *counters += local;
        }
    });
}

void PluckerAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                  TraversalCounters* counters) const {
    const plucker::PluckerView view = plucker::view_of(layout_);
    dispatch_policies(options_.triangle_test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters local;
        plucker::dispatch_layout(layout_.options, [&]<bool kBalanced, bool kStoredBoxes>() {
            plucker::CellCounter<kCount> steps{local};
            for (std::size_t i = 0; i < rays.size(); ++i) {
                occluded[i] = 0;
                if (!is_valid(rays[i])) continue;
                const PreparedRay<TriangleTestT> prepared(rays[i]);
                const auto block_ray = plucker::leaf_block_ray(prepared, geometry_);
                plucker::walk<kBalanced, kStoredBoxes>(
                    view, plucker::kTables, prepared.ray,
                    [&](const std::uint32_t* record, float limit) {
                        if constexpr (kCount) local.prims_tested += record[plucker::kTriangleCount];
                        if (plucker::for_each_leaf_block(
                                layout_, record, [&](const plucker::LeafBlock& block) {
                                    return occludes_block(geometry_, block, block_ray);
                                })) {
                            occluded[i] = 1;
                            return -kInfinity;  // any hit ends the walk
                        }
                        return limit;
                    },
                    steps);
            }
        });
        if constexpr (kCount) {
            local.rays = rays.size();
            *counters += local;
        }
    });
}

std::vector<std::uint32_t> PluckerAccel::leaves_along(const Ray& ray) const {
    std::vector<std::uint32_t> leaves;
    if (!is_valid(ray)) return leaves;
    const plucker::PluckerView view = plucker::view_of(layout_);
    plucker::dispatch_layout(layout_.options, [&]<bool kBalanced, bool kStoredBoxes>() {
        TraversalCounters unused;
        plucker::CellCounter<false> steps{unused};
        plucker::walk<kBalanced, kStoredBoxes>(
            view, plucker::kTables, ray,
            [&](const std::uint32_t* record, float limit) {
                leaves.push_back(static_cast<std::uint32_t>(record - layout_.cells.data()));
                return limit;
            },
            steps);
    });
    return leaves;
}

std::vector<BuildOptionRow> PluckerAccel::option_rows() {
    return {number_option("max_depth", "deepest level of the Plücker octree; 0: round(0.8 log2(N) - 5)",
                          &PluckerOptions::max_depth, 0, 16),
            number_option("leaf_size", "references a cell may hold before it is split",
                          &PluckerOptions::leaf_size, 1, 1 << 20),
            flag_option("balanced", "the 2:1 rule and links to leaves (the seed's layout)",
                        &PluckerOptions::balanced),
            flag_option("stored_boxes", "cell boxes stored, not recomputed from coordinates and level",
                        &PluckerOptions::stored_boxes),
            flag_option("morton", "cells in depth-first (Morton) order", &PluckerOptions::morton)};
}

}  // namespace lancer
