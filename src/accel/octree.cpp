#include "accel/octree.hpp"

#include <algorithm>
#include <cmath>

#include "accel/primitive_intersect.hpp"
#include "accel/tree_shape.hpp"

namespace lancer {
namespace {

// The distance of a plane is (p - o) * (1 / d): three roundings, relative error gamma(3). Intervals are
// widened by 2 gamma(3) where a test decides to skip something (the rule of intersect_box), so that rounding
// never drops a node whose true interval reaches the search interval: an extra node costs a visit, a
// missing one a wrong answer. Monotone, so the order of the walk's entry distances is kept.
constexpr float kSlack = 2.0f * gamma_bound(3);
[[nodiscard]] inline float rounded_up(float t) {
    return t * (t > 0.0f ? 1.0f + kSlack : 1.0f - kSlack);
}
[[nodiscard]] inline float rounded_down(float t) {
    return t * (t > 0.0f ? 1.0f - kSlack : 1.0f + kSlack);
}

[[nodiscard]] inline float min_component(const Vec3f& v) {
    return std::min(v.x, std::min(v.y, v.z));
}

// The ray as the walk uses it. Revelles' reflection is done in parameter space rather than by moving the
// origin (which would round it): on a mirrored axis the entry plane is the node's upper face and the exit
// plane its lower face, with the same formula (p - o) * inv. Zero components (of either sign) count as
// positive with inv = +inf, so that -0 is not mirrored into an inverted slab.
struct WalkRay {
    Vec3f origin;
    Vec3f inv_direction;
    int mirror = 0;  // `a` of the paper: bit k set when direction[k] < 0

    explicit WalkRay(const Ray& ray) : origin(ray.origin) {
        for (int axis = 0; axis < 3; ++axis) {
            const float d = ray.direction[axis];
            inv_direction[axis] = d == 0.0f ? kInfinity : 1.0f / d;
            if (d < 0.0f) mirror |= 1 << axis;
        }
    }

    // The parameter of plane coordinate p on `axis`. It is NaN only when the origin lies exactly on the
    // plane and inv is infinite (direction zero, or so small its reciprocal overflows): the ray does not
    // move along that axis, `nan_value` says how that case is read.
    [[nodiscard]] float distance(int axis, float p, float nan_value) const {
        const float t = (p - origin[axis]) * inv_direction[axis];
        return std::isnan(t) ? nan_value : t;
    }
};

// A node on the walk's stack: its parameters in the mirrored frame, where its children are, its integer
// coordinates (to place its mid planes) and the mirrored index of the next child to enter.
struct Frame {
    Vec3f t0, t1, tm;
    std::uint32_t first_child;
    std::uint32_t x, y, z;
    int next;
};

// Mid planes from the build's own face coordinates (OctreeCube::plane), not Revelles' 0.5 (t0 + t1): the
// average is NaN for a zero direction component (-inf + inf), and the exact planes make every node interval
// the slab interval of the build's box. A NaN (origin on the mid plane, no motion along the axis) reads
// -inf: the plane is behind, and the ray runs on in the far half, which holds it as a closed box.
inline void enter_node(const WalkRay& ray, const OctreeCube& cube, int level, Frame& frame) {
    const std::uint32_t coordinates[3] = {frame.x, frame.y, frame.z};
    for (int axis = 0; axis < 3; ++axis) {
        const float mid = cube.plane(axis, level + 1, 2u * coordinates[axis] + 1u);
        frame.tm[axis] = ray.distance(axis, mid, -kInfinity);
    }
    frame.next = revelles::first_child(frame.t0, frame.tm);
}

}  // namespace

void OctreeAccel::build_from(const Geometry& geometry, const BuildOptions& options) {
    Octree octree = build_octree(geometry, options.group<OctreeOptions>());
    cube_ = octree.cube;
    tolerance_ = octree.tolerance;
    nodes_.resize(octree.cells.size());
    std::transform(octree.cells.begin(), octree.cells.end(), nodes_.begin(), [](const OctreeCell& cell) {
        return cell.is_leaf() ? OctreeNode{cell.ref_begin, cell.ref_count()}
                              : OctreeNode{cell.first_child, OctreeNode::kInner};
    });
    references_ = std::move(octree.references);

    stats_ = AccelStats{};
    stats_.primitives = geometry.size();
    TreeShape shape{.nodes = nodes_.size(), .references = references_.size()};
    double sah_cost = 0.0;
    std::size_t depth_sum = 0, non_empty_leaves = 0;
    // SAH with unit costs, as the BVH's (docs/accel/bvh.md), so that the figures compare: the sum over inner
    // cells of A / A_root plus the sum over leaves of A / A_root times their references, where a level-l
    // cell of the root cube has A / A_root = 4^-l.
    for (const OctreeCell& cell : octree.cells) {
        const double area_ratio = std::ldexp(1.0, -2 * cell.level);
        if (!cell.is_leaf()) {
            sah_cost += area_ratio;
            continue;
        }
        ++shape.leaves;
        depth_sum += cell.level;
        shape.max_depth = std::max(shape.max_depth, static_cast<int>(cell.level));
        shape.max_refs_per_leaf = std::max<std::size_t>(shape.max_refs_per_leaf, cell.ref_count());
        sah_cost += area_ratio * cell.ref_count();
        if (cell.ref_count() == 0)
            ++shape.empty_leaves;
        else
            ++non_empty_leaves;
    }
    shape.mean_depth = static_cast<double>(depth_sum) / static_cast<double>(shape.leaves);
    // Over the non-empty leaves: what a ray pays in a leaf it has to test (empty leaves cost no test).
    shape.mean_refs_per_leaf =
        non_empty_leaves == 0 ? 0.0
                              : static_cast<double>(shape.references) / static_cast<double>(non_empty_leaves);
    stats_.figures = tree_figures(shape);
    stats_.figures.push_back(value_figure("sah_cost", sah_cost,
                                          "unit costs, as the BVH's: inner cells' areas plus leaves' areas "
                                          "times their references, over the root's"));
    stats_.memory_by_array = {{"nodes", nodes_.size() * sizeof(OctreeNode)},
                              {"references", references_.size() * sizeof(std::uint32_t)}};
}

std::size_t OctreeAccel::memory_bytes() const {
    std::size_t bytes = 0;
    for (const auto& [array, size] : stats_.memory_by_array)
        bytes += size;
    return bytes;
}

// Revelles et al. 2000, proc_subtree made iterative: the recursion's locals live in `stack`, one frame per
// level (the build never goes deeper than kOctreeMaxLevel). visit_leaf(node, limit) returns the new upper
// end of the search interval [tnear, limit] (the closest hit so far); a value below tnear ends the walk.
template <bool kCount, class LeafVisitor>
void OctreeAccel::walk(const Ray& ray, LeafVisitor&& visit_leaf, TraversalCounters* counters) const {
    // ENTRY: the root's parameters. A NaN (origin on a face plane, no motion along that axis) makes the slab
    // unbounded, as intersect_box does: the ray runs along the face, inside the closed box. The root is grown
    // by the geometric tolerance like every structure's outer box (docs/numerical-contract.md): a ray whose
    // whole [tnear, tfar] lies in that margin still finds the hit a kernel reports there
    // (fuzz/rays_fuzz.cpp).
    const WalkRay walk_ray(ray);
    Frame root{};
    for (int axis = 0; axis < 3; ++axis) {
        const bool mirrored = (walk_ray.mirror >> axis) & 1;
        const float lo = cube_.plane(axis, 0, 0) - tolerance_, hi = cube_.plane(axis, 0, 1) + tolerance_;
        root.t0[axis] = walk_ray.distance(axis, mirrored ? hi : lo, -kInfinity);
        root.t1[axis] = walk_ray.distance(axis, mirrored ? lo : hi, kInfinity);
    }
    float limit = ray.tfar;
    const float root_entry = max_component(root.t0), root_exit = rounded_up(min_component(root.t1));
    if (!(root_entry <= root_exit && rounded_down(root_entry) <= limit && root_exit >= ray.tnear)) return;
    if constexpr (kCount) ++counters->nodes_visited;
    if (nodes_[0].is_leaf()) {
        visit_leaf(0u, limit);
        return;
    }
    std::array<Frame, kOctreeMaxLevel + 1> stack;
    root.first_child = nodes_[0].index;
    enter_node(walk_ray, cube_, 0, root);
    stack[0] = root;
    int top = 0;

    while (top >= 0) {
        Frame& frame = stack[static_cast<std::size_t>(top)];
        // POP: every child of this node is done.
        if (frame.next == revelles::kExitParent) {
            --top;
            continue;
        }
        // ADVANCE: the child's parameters, then the state transition of table 3.
        const int child = frame.next;
        Vec3f t0, t1;
        for (int axis = 0; axis < 3; ++axis) {
            const bool upper = (child >> axis) & 1;
            t0[axis] = upper ? frame.tm[axis] : frame.t0[axis];
            t1[axis] = upper ? frame.t1[axis] : frame.tm[axis];
        }
        frame.next = revelles::next_child(child, frame.tm, frame.t1);
        // Children come front to back, each entered where the previous one is left: once one starts beyond
        // the closest hit (or tfar), so does everything after it on the stack.
        if (rounded_down(max_component(t0)) > limit) return;
        if (rounded_up(min_component(t1)) < ray.tnear) continue;  // wholly behind the ray's start
        const int real_child = child ^ walk_ray.mirror;
        const std::uint32_t node_index = frame.first_child + static_cast<std::uint32_t>(real_child);
        const OctreeNode node = nodes_[node_index];
        if constexpr (kCount) ++counters->nodes_visited;
        if (node.is_leaf()) {
            // LEAF: a hit found here may lie beyond this leaf's exit (a primitive spanning several
            // leaves); it only narrows the interval, and the entry test above ends the walk when due.
            limit = visit_leaf(node_index, limit);
            if (limit < ray.tnear) return;
            continue;
        }
        // PUSH
        Frame& pushed = stack[static_cast<std::size_t>(top + 1)];
        pushed.t0 = t0;
        pushed.t1 = t1;
        pushed.first_child = node.index;
        pushed.x = 2u * frame.x + static_cast<std::uint32_t>(real_child & 1);
        pushed.y = 2u * frame.y + static_cast<std::uint32_t>((real_child >> 1) & 1);
        pushed.z = 2u * frame.z + static_cast<std::uint32_t>((real_child >> 2) & 1);
        enter_node(walk_ray, cube_, top + 1, pushed);
        ++top;
    }
}

template <bool kAnyHit, bool kCount, class TriangleTestT>
bool OctreeAccel::trace(const PreparedRay<TriangleTestT>& prepared, Hit& best,
                        TraversalCounters& counts) const {
    bool hit = false;
    walk<kCount>(
        prepared.ray,
        [&](std::uint32_t node_index, float limit) {
            const OctreeNode& leaf = nodes_[node_index];
            if constexpr (kAnyHit) {
                for (std::uint32_t r = leaf.index; r < leaf.index + leaf.count; ++r) {
                    if constexpr (kCount) ++counts.prims_tested;
                    if (occludes(geometry_, references_[r], prepared)) {
                        hit = true;
                        return -kInfinity;  // any hit ends the walk
                    }
                }
                return limit;
            } else {
                for (std::uint32_t r = leaf.index; r < leaf.index + leaf.count; ++r)
                    intersect_primitive(geometry_, references_[r], prepared, best);
                if constexpr (kCount) counts.prims_tested += leaf.count;
                return best.hit() ? best.t : prepared.ray.tfar;
            }
        },
        &counts);
    return kAnyHit ? hit : best.hit();
}

template class SingleRayAccel<OctreeAccel>;

std::vector<std::uint32_t> OctreeAccel::leaves_along(const Ray& ray) const {
    std::vector<std::uint32_t> leaves;
    if (!is_valid(ray)) return leaves;
    walk<false>(
        ray,
        [&](std::uint32_t node_index, float limit) {
            leaves.push_back(node_index);
            return limit;
        },
        nullptr);
    return leaves;
}

std::vector<BuildOptionRow> OctreeAccel::option_rows() {
    return {
        number_option("max_depth", "deepest level of the classic octree", &OctreeOptions::max_depth, 0, 20),
        number_option("leaf_size", "references a node may hold before it is split", &OctreeOptions::leaf_size,
                      1, 1 << 20)};
}

}  // namespace lancer
