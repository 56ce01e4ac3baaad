// Refitting the BVHs to moved triangles (Wald, Boulos & Shirley, "Ray tracing deformable scenes using
// dynamic bounding volume hierarchies", ACM TOG 2007, section 4.1): the tree and its leaves stay as built,
// each box becomes the union of what it holds, bottom-up, subtrees in parallel. docs/accel/refit.md has the
// design note.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/triangle_block.hpp"
#include "accel/tree_shape.hpp"

namespace lancer {

// What the builders grow every box by, for `geometry` whose primitives that can be hit lie in `hit_bounds`
// (Accel::bounds): the geometric tolerance of the tree's root box. A refit to the positions a tree was built
// on thus gives it back bit for bit.
[[nodiscard]] float refit_margin(const Geometry& geometry, const Box3f& hit_bounds);

// Recomputes the boxes of `nodes`, a depth-first layout of build_bvh over `prim_indices`, from `geometry`'s
// primitives, each grown by `margin`. Returns the SAH cost of the refitted tree as bvh_sah_cost defines it.
double refit_bvh(const Geometry& geometry, std::span<const std::uint32_t> prim_indices,
                 HugePageVector<BvhNode>& nodes, float margin);

// The same for a tree of build_bvh_over_boxes whose references `prim_indices` now have the boxes
// boxes[id], grown by the tolerance of their union as the build grows them.
double refit_bvh_over_boxes(std::span<const Box3f> boxes, std::span<const std::uint32_t> prim_indices,
                            HugePageVector<BvhNode>& nodes);

// The same for a wide BVH: rewrites the triangles of its leaf blocks from `geometry` and recomputes its child
// boxes. Returns the SAH cost as WideBvhAccel::stats() defines it.
template <int W>
double refit_wide_bvh(const Geometry& geometry, HugePageVector<WideBvhNode<W>>& nodes,
                      HugePageVector<TriangleBlock<W>>& blocks, float margin);

// The ratio an update reports: a refitted tree's SAH cost over its cost as built, 1 for a tree without cost
// (an empty one).
[[nodiscard]] inline double refit_sah_ratio(double refitted_cost, double built_cost) {
    return built_cost > 0.0 ? refitted_cost / built_cost : 1.0;
}

// A BVH's figures (its AccelStats) from its walk's totals: the tree's shape with its means over the leaves
// (every leaf of a BVH holds a primitive), the SAH cost and, after refits, its ratio to the cost as built.
[[nodiscard]] inline std::vector<AccelFigure> bvh_figures(TreeShape shape, double depth_sum, double sah_cost,
                                                          double sah_ratio) {
    if (shape.leaves > 0) {
        shape.mean_depth = depth_sum / static_cast<double>(shape.leaves);
        shape.mean_refs_per_leaf = static_cast<double>(shape.references) / static_cast<double>(shape.leaves);
    }
    std::vector<AccelFigure> figures = tree_figures(shape);
    figures.push_back(
        value_figure("sah_cost", sah_cost,
                     "unit node and primitive costs: nodes' areas plus leaves' areas times their "
                     "primitives, over the root's"));
    figures.push_back(
        value_figure("sah_ratio", sah_ratio, "the SAH cost over the cost as last built, after refits"));
    return figures;
}

// The SAH cost of a wide BVH: the sum over nodes of the area of the node's box, and over leaves of their
// area times their primitives, over the root's area (the primitive count where the root has no area).
template <int W>
double wide_bvh_sah_cost(std::span<const WideBvhNode<W>> nodes);

}  // namespace lancer
