// The 4- and 8-wide BVHs: structural invariants of the collapse, shallower than the binary tree, and the
// SIMD box test equal to intersect_box (hit or miss and entry distance) on random and face-plane rays.
// Agreement with brute force is the oracle test's (every registered structure).
#include "accel/bvh_wide.hpp"

#include <gtest/gtest.h>

#include <random>

#include "accel/build_util.hpp"
#include "lancer/generate.hpp"
#include "test_scenes.hpp"

namespace lancer {
namespace {

using testing::knot_triangles;

bool contains(const Box3f& outer, const Box3f& inner) {
    return outer.lo.x <= inner.lo.x && outer.lo.y <= inner.lo.y && outer.lo.z <= inner.lo.z &&
           outer.hi.x >= inner.hi.x && outer.hi.y >= inner.hi.y && outer.hi.z >= inner.hi.z;
}

bool is_inverted(const Box3f& box) {
    return box.lo.x == kInfinity && box.lo.y == kInfinity && box.lo.z == kInfinity &&
           box.hi.x == -kInfinity && box.hi.y == -kInfinity && box.hi.z == -kInfinity;
}

// Every primitive in exactly one leaf slot whose box contains it; inner slots contain their node's children;
// empty slots are inverted, hold nothing and come after the used ones; every node but a tiny scene's root
// has at least two children.
template <int W>
void expect_valid_wide_hierarchy(const WideBvhAccel<W>& bvh, const Geometry& geometry, int max_leaf_size) {
    const std::vector<WideBvhNode<W>>& nodes = bvh.nodes();
    std::vector<int> seen(geometry.size(), 0);
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        const WideBvhNode<W>& node = nodes[i];
        int used = 0;
        for (int slot = 0; slot < W; ++slot) {
            const Box3f box = node.child_bounds(slot);
            if (node.is_empty(slot)) {
                ASSERT_TRUE(is_inverted(box)) << "node " << i << " slot " << slot;
                ASSERT_EQ(node.prim_count[slot], 0u);
                continue;
            }
            ASSERT_EQ(used, slot) << "node " << i << ": a used slot after an empty one";
            ++used;
            if (node.prim_count[slot] > 0) {
                ASSERT_LE(node.prim_count[slot], static_cast<std::uint32_t>(max_leaf_size));
                for (std::uint32_t k = node.child[slot]; k < node.child[slot] + node.prim_count[slot]; ++k) {
                    const std::uint32_t prim = bvh.prim_indices()[k];
                    ++seen[prim];
                    ASSERT_TRUE(contains(box, primitive_bounds(geometry, prim))) << "node " << i;
                }
            } else {
                ASSERT_GT(node.child[slot], i);
                ASSERT_LT(node.child[slot], nodes.size());
                const WideBvhNode<W>& child = nodes[node.child[slot]];
                for (int child_slot = 0; child_slot < W; ++child_slot) {
                    if (child.is_empty(child_slot)) continue;
                    ASSERT_TRUE(contains(box, child.child_bounds(child_slot)));
                }
            }
        }
        ASSERT_GE(used, i == 0 ? 1 : 2) << "node " << i;
    }
    for (std::size_t prim = 0; prim < seen.size(); ++prim)
        ASSERT_EQ(seen[prim], 1) << "primitive " << prim;
    const AccelStats stats = bvh.stats();
    EXPECT_EQ(stats.references, geometry.size());
    EXPECT_EQ(stats.nodes, nodes.size() + stats.leaves);
    EXPECT_EQ(bvh.memory_bytes(),
              nodes.size() * sizeof(WideBvhNode<W>) + geometry.size() * sizeof(std::uint32_t));
}

template <int W>
void check_structure(const Geometry& geometry) {
    for (int leaf : {1, 4, 16}) {
        BuildOptions options;
        options.bvh.max_leaf_size = leaf;
        WideBvhAccel<W> wide;
        wide.build(geometry, options);
        expect_valid_wide_hierarchy(wide, geometry, leaf);
    }
}

TEST(WideBvh, CollapseGivesValidHierarchies) {
    const std::vector<Triangle> triangles = knot_triangles(400);
    const std::vector<Sphere> spheres = {{{0, 0, 0}, 0.3f, 0}, {{1, 1, 0}, 0.1f, 0}};
    const Geometry geometry{triangles, spheres};
    check_structure<4>(geometry);
    check_structure<8>(geometry);
}

TEST(WideBvh, TinyScenesHaveOneRootNode) {
    const std::vector<Triangle> one = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    Bvh8Accel wide;
    wide.build({one, {}}, {});
    ASSERT_EQ(wide.nodes().size(), 1u);
    EXPECT_EQ(wide.nodes()[0].prim_count[0], 1u);
    for (int slot = 1; slot < 8; ++slot)
        EXPECT_TRUE(wide.nodes()[0].is_empty(slot));
    Bvh4Accel empty;
    empty.build({}, {});
    EXPECT_TRUE(empty.nodes().empty());
    EXPECT_EQ(empty.stats().leaves, 0u);
}

TEST(WideBvh, FewerNodesAndShallowerThanTheBinaryTree) {
    const std::vector<Triangle> triangles = knot_triangles(2000);
    const Geometry geometry{triangles, {}};
    BvhAccel binary;
    binary.build(geometry, {});
    Bvh4Accel bvh4;
    bvh4.build(geometry, {});
    Bvh8Accel bvh8;
    bvh8.build(geometry, {});
    const AccelStats b = binary.stats(), s4 = bvh4.stats(), s8 = bvh8.stats();
    // Same leaves, collapsed inner levels.
    EXPECT_EQ(s4.leaves, b.leaves);
    EXPECT_EQ(s8.leaves, b.leaves);
    EXPECT_LT(s4.nodes, b.nodes);
    EXPECT_LT(s8.nodes, s4.nodes);
    EXPECT_LT(s4.max_depth, b.max_depth);
    EXPECT_LT(s8.max_depth, s4.max_depth);
    EXPECT_LT(s4.mean_depth, b.mean_depth);
    EXPECT_LT(s8.mean_depth, s4.mean_depth);
    EXPECT_GT(s8.sah_cost, 0.0);
}

// Random nodes and rays built to hit the slab test's edge cases: coordinates on a coarse grid so that origins
// lie exactly in face planes, zero and negative-zero direction components, flat boxes, empty slots, and
// intervals [tnear, tfar] that cut boxes.
template <int W>
void check_box_test_against_intersect_box(std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> grid(-4, 4);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_int_distribution<int> choice(0, 7);
    auto coordinate = [&] { return choice(rng) < 4 ? static_cast<float>(grid(rng)) : 4.0f * unit(rng); };
    std::size_t hits = 0, nan_slab_hits = 0, face_plane_rays = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        WideBvhNode<W> node;
        for (int slot = 0; slot < W; ++slot) {
            if (choice(rng) == 0) continue;  // an empty slot
            for (int axis = 0; axis < 3; ++axis) {
                float a = coordinate(), b = choice(rng) == 0 ? a : coordinate();
                if (a > b) std::swap(a, b);
                node.bounds[WideBvhNode<W>::kLo][axis][slot] = a;
                node.bounds[WideBvhNode<W>::kHi][axis][slot] = b;
            }
        }
        Ray ray{
            {coordinate(), coordinate(), coordinate()}, {unit(rng), unit(rng), unit(rng)}, 0.0f, kInfinity};
        for (int axis = 0; axis < 3; ++axis) {
            const int pick = choice(rng);
            if (pick == 0) ray.direction[axis] = 0.0f;
            if (pick == 1) ray.direction[axis] = -0.0f;
            if (pick <= 1) ++face_plane_rays;
        }
        if (!is_valid(ray)) continue;
        if (choice(rng) < 3) ray.tnear = 2.0f * unit(rng), ray.tfar = ray.tnear + 4.0f * std::abs(unit(rng));
        const SlabRay slab(ray);
        const WideRay wide_ray(slab);
        float entry[W], scalar_entry[W];
        const unsigned mask = intersect_children(node, wide_ray, ray.tnear, ray.tfar, entry);
        const unsigned scalar_mask =
            intersect_children_scalar(node, wide_ray, ray.tnear, ray.tfar, scalar_entry);
        for (int slot = 0; slot < W; ++slot) {
            const bool hit = (mask >> slot) & 1u;
            const bool scalar_hit = (scalar_mask >> slot) & 1u;
            ASSERT_EQ(hit, scalar_hit) << "trial " << trial << " slot " << slot;
            if (node.is_empty(slot)) {
                ASSERT_FALSE(hit) << "trial " << trial << ": an empty slot was hit";
                continue;
            }
            float expected_entry, expected_exit;
            const bool expected = intersect_box(slab, node.child_bounds(slot), ray.tnear, ray.tfar,
                                                expected_entry, expected_exit);
            ASSERT_EQ(hit, expected) << "trial " << trial << " slot " << slot;
            ASSERT_EQ(entry[slot], expected_entry) << "trial " << trial << " slot " << slot;
            ASSERT_EQ(scalar_entry[slot], expected_entry) << "trial " << trial << " slot " << slot;
            hits += hit;
            for (int axis = 0; axis < 3; ++axis) {
                const bool in_face_plane =
                    ray.direction[axis] == 0.0f &&
                    (ray.origin[axis] == node.bounds[WideBvhNode<W>::kLo][axis][slot] ||
                     ray.origin[axis] == node.bounds[WideBvhNode<W>::kHi][axis][slot]);
                nan_slab_hits += hit && in_face_plane;
            }
        }
    }
    // The sets are not degenerate: many hits, many of them by rays in a face plane (the NaN slab rule).
    EXPECT_GT(hits, 4000u);
    EXPECT_GT(nan_slab_hits, 100u);
    EXPECT_GT(face_plane_rays, 10000u);
}

TEST(WideBvh, SimdBoxTestEqualsIntersectBox) {
    check_box_test_against_intersect_box<4>(7);
    check_box_test_against_intersect_box<8>(8);
}

TEST(WideBvh, CountersSeeFewerNodesThanTheBinaryTree) {
    const std::vector<Triangle> triangles = knot_triangles(400);
    BvhAccel binary;
    binary.build({triangles, {}}, {});
    Bvh8Accel wide;
    wide.build({triangles, {}}, {});
    const Ray through_tube{{1.5f, 0.0f, 5.0f}, {0, 0, -1}, 0.0f, kInfinity};
    Hit binary_hit, wide_hit;
    TraversalCounters binary_counters, wide_counters;
    binary.intersect({&through_tube, 1}, {&binary_hit, 1}, &binary_counters);
    wide.intersect({&through_tube, 1}, {&wide_hit, 1}, &wide_counters);
    ASSERT_TRUE(wide_hit.hit());
    EXPECT_EQ(wide_hit.prim, binary_hit.prim);
    EXPECT_EQ(wide_hit.t, binary_hit.t);
    EXPECT_LT(wide_counters.nodes_visited, binary_counters.nodes_visited);
}

}  // namespace
}  // namespace lancer
