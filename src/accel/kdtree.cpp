#include "accel/kdtree.hpp"

#include <array>
#include <cmath>
#include <limits>

#include "accel/primitive_intersect.hpp"
#include "accel/tree_shape.hpp"

namespace lancer {
namespace {

constexpr float kWidening = 2.0f * gamma_bound(3);
constexpr float kSmallestNormal = std::numeric_limits<float>::min();

// An interval certain to hold the parameters where the ray is within the geometric tolerance of a plane
// whose crossing parameter was computed as t. (plane - o) * (1 / d) rounds three times, a relative error
// of at most gamma(3) (pbrt-v4 section 6.8), and (plane - o) / d twice: widening by 2 gamma(3) leaves room
// for the rounding of the widening product itself. `slack` (WalkRay) adds the parameter distance of the
// geometric tolerance along the ray, and covers a product that underflowed into the subnormals.
// Infinities stay infinite.
struct Bracket {
    float lo, hi;
};

[[nodiscard]] inline Bracket bracket(float t, float slack) {
    const float down = t >= 0.0f ? 1.0f - kWidening : 1.0f + kWidening;
    const float up = t >= 0.0f ? 1.0f + kWidening : 1.0f - kWidening;
    return {t * down - slack, t * up + slack};
}

// The ray as the walk reads it, axis by axis.
struct WalkRay {
    std::array<float, 3> origin, direction, inv_direction;
    // tolerance / |d| + FLT_MIN: the parameter distance over which the ray moves by the tolerance along an
    // axis (read only where d != 0; infinite for a subnormal d, which then never culls a child).
    std::array<float, 3> slack;

    WalkRay(const Ray& ray, float tolerance) {
        for (int axis = 0; axis < 3; ++axis) {
            const auto i = static_cast<std::size_t>(axis);
            origin[i] = ray.origin[axis], direction[i] = ray.direction[axis];
            inv_direction[i] = 1.0f / direction[i];
            const float inverse_length = std::fabs(inv_direction[i]);
            slack[i] = inverse_length < kInfinity ? tolerance * inverse_length + kSmallestNormal : kInfinity;
        }
    }
};

// [tmin, tmax]: the part of [tnear, tfar] in the root box grown by the tolerance, bracketed at both ends.
// A zero direction component keeps the ray in its slab or out of it for good (on a face counts as in:
// boxes are closed); for a subnormal one, whose reciprocal overflowed, the slab distances are divided.
[[nodiscard]] inline bool clip_to_box(const WalkRay& ray, const Box3f& box, float tolerance, float tnear,
                                      float tfar, float& tmin, float& tmax) {
    if (box.empty()) return false;
    tmin = tnear, tmax = tfar;
    for (int axis = 0; axis < 3; ++axis) {
        const auto i = static_cast<std::size_t>(axis);
        const float o = ray.origin[i], d = ray.direction[i], inv = ray.inv_direction[i];
        if (d == 0.0f) {
            if (o < box.lo[axis] - tolerance || o > box.hi[axis] + tolerance) return false;
            continue;
        }
        const bool finite_inverse = std::fabs(inv) < kInfinity;
        float t0 = finite_inverse ? (box.lo[axis] - o) * inv : (box.lo[axis] - o) / d;
        float t1 = finite_inverse ? (box.hi[axis] - o) * inv : (box.hi[axis] - o) / d;
        if (t0 > t1) std::swap(t0, t1);
        tmin = std::max(tmin, bracket(t0, ray.slack[i]).lo);
        tmax = std::min(tmax, bracket(t1, ray.slack[i]).hi);
    }
    return tmin <= tmax;
}

// 12 bytes: a far child still to visit and its parameter interval.
struct StackEntry {
    std::uint32_t node;
    float tmin, tmax;
};
static_assert(sizeof(StackEntry) == 12);

}  // namespace

// Front-to-back walk with a stack of far children (Havran's TA_rec_B in the iterative form of pbrt-v3's
// KdTreeAccel::Intersect; the "Lancer de rayon" slides, "KD-tree : parcours récursif": the three cases t* >
// tmax, t* < tmin, tmin <= t* <= tmax). Each node is entered with an interval [tmin, tmax] that contains
// every parameter where the ray is within the geometric tolerance of the node's box
// (docs/numerical-contract.md, "Boxes"): the split crossing is bracketed (bracket() above), the near child
// gets [tmin, hi], the far one [lo, tmax]. A child is skipped only when its interval is empty, so no rounding
// skips a leaf the ray passes through, and a hit the kernel reports a hair outside its primitive's leaves is
// still found.
template <bool kAnyHit, bool kCount, class TriangleTestT>
bool KdTreeAccel::trace(const PreparedRay<TriangleTestT>& prepared, Hit& best,
                        TraversalCounters& counts) const {
    const float tolerance = tree_.tolerance;
    const WalkRay ray(prepared.ray, tolerance);
    float tmin, tmax;
    if (!clip_to_box(ray, tree_.bounds, tolerance, prepared.ray.tnear, prepared.ray.tfar, tmin, tmax))
        return false;
    const std::array<float, 3>& origin = ray.origin;
    const std::array<float, 3>& direction = ray.direction;
    const std::array<float, 3>& inv_direction = ray.inv_direction;

    const KdNode* const nodes = tree_.nodes.data();
    const std::uint32_t* const references = tree_.references.data();
    std::array<StackEntry, kKdTreeMaxDepth> stack;  // one entry per inner node on the path at most
    std::size_t top = 0;
    std::uint32_t index = 0;
    while (true) {
        // DESCEND to the leaf where the interval begins, pushing the far children the ray also reaches.
        const KdNode* node = &nodes[index];
        if constexpr (kCount) ++counts.nodes_visited;
        while (!node->is_leaf()) {
            const auto axis = static_cast<std::size_t>(node->axis());
            const float split = node->split();
            const std::uint32_t below = index + 1, above = node->above_child();
            float t_split = (split - origin[axis]) * inv_direction[axis];
            if (!(std::fabs(t_split) < kInfinity)) [[unlikely]] {
                if (direction[axis] == 0.0f) {
                    // PARALLEL: the ray keeps its distance to the plane (0 * inf = NaN when it lies in it);
                    // within the tolerance of the plane it reaches both children over the whole interval.
                    const bool reaches_below = origin[axis] <= split + tolerance;
                    const bool reaches_above = origin[axis] >= split - tolerance;
                    if (reaches_below && reaches_above) stack[top++] = {above, tmin, tmax};
                    index = reaches_below ? below : above;
                    node = &nodes[index];
                    if constexpr (kCount) ++counts.nodes_visited;
                    continue;
                }
                t_split = (split - origin[axis]) / direction[axis];  // 1 / d overflowed: d is subnormal
            }
            const Bracket crossing = bracket(t_split, ray.slack[axis]);
            const bool below_first = direction[axis] > 0.0f;
            const std::uint32_t first = below_first ? below : above, second = below_first ? above : below;
            if (crossing.hi < tmin) {  // crossed before the interval: only the far child
                index = second;
            } else if (crossing.lo > tmax) {  // crosses after it: only the near child
                index = first;
            } else {
                stack[top++] = {second, std::max(tmin, crossing.lo), tmax};
                index = first;
                tmax = std::min(tmax, crossing.hi);
            }
            node = &nodes[index];
            if constexpr (kCount) ++counts.nodes_visited;
        }

        // LEAF: the primitive tests clip to [tnear, best.t], not to the leaf's interval, so a primitive that
        // spans several leaves is found wherever it is hit.
        const std::uint32_t count = node->primitive_count();
        const std::uint32_t* const prims = node->primitives(references);
        for (std::uint32_t i = 0; i < count; ++i) {
            if constexpr (kAnyHit) {
                if (occludes(geometry_, prims[i], prepared)) {
                    if constexpr (kCount) counts.prims_tested += i + 1;
                    return true;
                }
            } else {
                intersect_primitive(geometry_, prims[i], prepared, best);
            }
        }
        if constexpr (kCount) counts.prims_tested += count;

        // POP the nearest far child. Early exit (pbrt-v3): a node whose interval starts after the best hit
        // cannot hold a closer one. The test is on that node's bracketed tmin, not on the tmax of the leaf
        // just left, so a hit found beyond that leaf (in a primitive spanning several leaves) never ends the
        // walk early, and a hit at exactly the next node's tmin still lets that node offer an equal-t
        // primitive of smaller index.
        do {
            if (top == 0) return best.hit();
            --top;
        } while (!kAnyHit && best.t < stack[top].tmin);
        index = stack[top].node;
        tmin = stack[top].tmin;
        tmax = stack[top].tmax;
    }
}

template class SingleRayAccel<KdTreeAccel>;

AccelStats KdTreeAccel::stats() const {
    const KdTreeBuildStats& built = tree_.stats;
    AccelStats stats;
    stats.build_ms = build_ms_;
    stats.primitives = geometry_.size();
    stats.figures = tree_figures({.nodes = tree_.nodes.size(),
                                  .leaves = built.leaves,
                                  .empty_leaves = built.empty_leaves,
                                  .references = built.references,
                                  .max_depth = built.max_depth,
                                  .mean_depth = built.mean_depth,
                                  .mean_refs_per_leaf = built.mean_refs_per_leaf,
                                  .max_refs_per_leaf = built.max_refs_per_leaf});
    // Whichever cost model built the tree, so that trees compare.
    stats.figures.push_back(value_figure("sah_cost", built.sah_cost,
                                         "Ct SA(inner) + Ci N SA(leaf) over SA(root), the options' costs, no "
                                         "empty bonus"));
    stats.memory_by_array = {{"nodes", tree_.nodes.size() * sizeof(KdNode)},
                             {"references", tree_.references.size() * sizeof(std::uint32_t)}};
    return stats;
}

std::size_t KdTreeAccel::memory_bytes() const {
    return tree_.nodes.size() * sizeof(KdNode) + tree_.references.size() * sizeof(std::uint32_t);
}

std::vector<BuildOptionRow> KdTreeAccel::option_rows() {
    return {
        choice_option<KdTreeOptions, KdTreeCost>(
            "cost", "the split cost: Wald & Havran's SAH, or Ferreira & Mendoza's", &KdTreeOptions::cost,
            {{"wald-havran", KdTreeCost::WaldHavran}, {"seed003", KdTreeCost::Seed003}}),
        number_option("traversal_cost", "the SAH's cost of a traversal step", &KdTreeOptions::traversal_cost,
                      0.0f, 1e6f),
        number_option("intersection_cost", "the SAH's cost of a primitive test",
                      &KdTreeOptions::intersection_cost, 1e-3f, 1e6f),
        number_option("empty_bonus", "the SAH's bonus for an empty side", &KdTreeOptions::empty_bonus, 0.0f,
                      1.0f),
        number_option("max_depth", "deepest level; 0: 8 + 1.3 log2(N)", &KdTreeOptions::max_depth, 0, 64)};
}

}  // namespace lancer
