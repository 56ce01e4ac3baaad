// The classic octree (the "Lancer de rayon" slides, "grille adaptative : octree"; Portalez & Duguet 2016,
// sections 1 and 2.2): the top-down build of octree_build.hpp, walked with the parametric top-down algorithm
// of Revelles, Urena & Lastra, "An Efficient Parametric Algorithm for Octree Traversal" (WSCG 2000),
// iteratively over a fixed-size stack.
//
// Revelles' method works in a mirrored frame where every direction component is >= 0. There a node is
// described by three parameters per axis: t0 (entry plane), t1 (exit plane) and tm (mid plane); its children
// are visited front to back by two tables: the first child from the plane the ray enters by (tables 1 and
// 2 of the paper) and each next child from the plane it leaves by (table 3). A mirrored child index c is the
// real child c ^ a, where bit k of `a` is set when the direction is negative on axis k. Child indices here
// use the build's order, x_bit | y_bit << 1 | z_bit << 2 (the paper numbers them x << 2 | y << 1 | z).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "accel/octree_build.hpp"
#include "accel/options.hpp"
#include "accel/single_ray.hpp"

namespace lancer {

namespace revelles {

inline constexpr int kExitParent = 8;

// Tables 1 and 2: the entry plane is the one of the largest t0 (ties resolved as in the paper's code:
// x only when strictly largest, then y over z); the first child has bit k set for each other axis k whose
// mid plane the ray has already crossed at the entry, tm[k] < t_entry.
struct FirstChildRule {
    int other_axis_a, other_axis_b;
};
inline constexpr std::array<FirstChildRule, 3> kFirstChildRules = {{
    {1, 2},  // entry plane YZ (x): bit 2 if tm.y < t0.x, bit 4 if tm.z < t0.x
    {0, 2},  // entry plane XZ (y): bit 1 if tm.x < t0.y, bit 4 if tm.z < t0.y
    {0, 1},  // entry plane XY (z): bit 1 if tm.x < t0.z, bit 2 if tm.y < t0.z
}};

[[nodiscard]] inline int first_child(const Vec3f& t0, const Vec3f& tm) {
    const int entry_axis = (t0.x > t0.y && t0.x > t0.z) ? 0 : (t0.y > t0.z ? 1 : 2);
    const float t_entry = t0[entry_axis];
    const FirstChildRule& rule = kFirstChildRules[static_cast<std::size_t>(entry_axis)];
    return (tm[rule.other_axis_a] < t_entry ? 1 << rule.other_axis_a : 0) |
           (tm[rule.other_axis_b] < t_entry ? 1 << rule.other_axis_b : 0);
}

// Table 3: the child entered after child c when the ray leaves c through its plane normal to axis k
// (kExitParent when that plane is the parent's own face).
inline constexpr std::array<std::array<std::uint8_t, 3>, 8> kNextChild = {{
    {1, 2, 4},  // 0
    {8, 3, 5},  // 1
    {3, 8, 6},  // 2
    {8, 8, 7},  // 3
    {5, 6, 8},  // 4
    {8, 7, 8},  // 5
    {7, 8, 8},  // 6
    {8, 8, 8},  // 7
}};

// The exit plane of child c is the one of smallest exit parameter (tm on an axis where c is the lower
// half, t1 where it is the upper half). On a tie (the ray leaves through an edge or a corner) a move inside
// the parent wins over leaving it, so that a child the ray only grazes is visited rather than skipped:
// every transition sets one bit, so at most 4 children are visited whatever the values (even NaN).
[[nodiscard]] inline int next_child(int c, const Vec3f& tm, const Vec3f& t1) {
    int exit_axis = 0;
    float exit_t = (c & 1) ? t1.x : tm.x;
    for (int axis = 1; axis < 3; ++axis) {
        const bool leaves_parent = (c >> axis) & 1;
        const float t = leaves_parent ? t1[axis] : tm[axis];
        const bool best_leaves_parent = (c >> exit_axis) & 1;
        if (t < exit_t || (t == exit_t && best_leaves_parent && !leaves_parent)) exit_axis = axis, exit_t = t;
    }
    return kNextChild[static_cast<std::size_t>(c)][static_cast<std::size_t>(exit_axis)];
}

}  // namespace revelles

// 8 bytes: the trace-time node; node i is cell i of the build (children contiguous, same order).
struct OctreeNode {
    static constexpr std::uint32_t kInner = 0xFFFFFFFFu;
    std::uint32_t index = 0;       // 4: inner: first of the 8 children; leaf: first reference
    std::uint32_t count = kInner;  // 4: leaf: number of references; inner: kInner

    [[nodiscard]] bool is_leaf() const { return count != kInner; }
};
static_assert(sizeof(OctreeNode) == 8);

class OctreeAccel final : public SingleRayAccel<OctreeAccel> {
  public:
    // The `--set` keys of this structure's option group (accel/options.hpp).
    [[nodiscard]] static std::vector<BuildOptionRow> option_rows();
    [[nodiscard]] std::string_view name() const override { return "octree"; }
    [[nodiscard]] AccelStats stats() const override {
        AccelStats stats = stats_;
        stats.build_ms = build_ms_;
        return stats;
    }
    [[nodiscard]] std::size_t memory_bytes() const override;

    // The leaves (node indices, equal to build_octree's cell indices) the walk enters along the ray over
    // [tnear, tfar], in order, without testing primitives: the traversal seen from outside, for tests.
    [[nodiscard]] std::vector<std::uint32_t> leaves_along(const Ray& ray) const;

  private:
    friend SingleRayAccel<OctreeAccel>;

    void build_from(const Geometry& geometry, const BuildOptions& options);
    // SingleRayAccel's contract: walk() with the leaves' primitive tests.
    template <bool kAnyHit, bool kCount, class TriangleTestT>
    bool trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counts) const;

    template <bool kCount, class LeafVisitor>
    void walk(const Ray& ray, LeafVisitor&& visit_leaf, TraversalCounters* counters) const;

    OctreeCube cube_;
    float tolerance_ = 0.0f;  // the scene's geometric tolerance: the root's outer faces are grown by it
    std::vector<OctreeNode> nodes_;
    std::vector<std::uint32_t> references_;
    AccelStats stats_;  // build_ms excepted
};

extern template class SingleRayAccel<OctreeAccel>;

}  // namespace lancer
