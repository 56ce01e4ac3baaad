// The classic octree: the build's invariants (octant geometry of the cells, references wherever a primitive
// overlaps, depth and leaf-size limits, the stopping rule on coincident triangles), Revelles' tables against
// slab tests, the walk's leaf order against slab tests on every leaf, and agreement with brute force where
// the traversal is most fragile (rays in cell planes, a hit beyond its leaf, max_depth 0).
#include "accel/octree.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>

#include "accel/brute.hpp"
#include "accel/build_util.hpp"
#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "support/brute_force_agreement.hpp"
#include "support/cell_plane_rays.hpp"
#include "support/crossed_leaves.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::TestScene;

TestScene sphere_and_spheres() {
    TestScene scene;
    make_icosphere(3, {0.2f, -0.1f, 0.3f}, 1.0f).append_triangles(scene.triangles);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (int i = 0; i < 20; ++i)
        scene.spheres.push_back(
            {{4 * unit(rng) - 2, 4 * unit(rng) - 2, unit(rng) - 0.5f}, 0.1f + 0.2f * unit(rng), 0});
    return scene;
}

TestScene triangle_soup() {
    TestScene scene;
    std::mt19937 rng(11);
    testing::append_triangle_soup(rng, 1500, 10.0f, 10, 3.0f, 0.4f, scene.triangles);
    return scene;
}

TestScene coincident_triangles() {
    TestScene scene;
    scene.triangles.assign(3000, Triangle{{0, 0, 0}, {1, 0, 0.5f}, {0, 1, 1}});
    scene.triangles.push_back({{-1, -1, 2}, {2, -1, 2}, {-1, 2, 2}});
    return scene;
}

OctreeOptions octree_options(int max_depth, int leaf_size) {
    OctreeOptions options;
    options.max_depth = max_depth;
    options.leaf_size = leaf_size;
    return options;
}

BuildOptions build_options_with(OctreeOptions octree, TriangleTest test = TriangleTest::MollerTrumbore) {
    BuildOptions options = build_options(test);
    options.group<OctreeOptions>() = octree;
    return options;
}

// ---------------------------------------------------------------------------------------------------------
// Build invariants

TEST(OctreeBuild, ChildrenAreTheOctantsOfTheirParent) {
    for (const TestScene& scene : {sphere_and_spheres(), triangle_soup()}) {
        const Octree octree = build_octree(scene.geometry(), octree_options(6, 4));
        ASSERT_GT(octree.cells.size(), 1u);
        const OctreeCell& root = octree.cells[0];
        EXPECT_EQ(root.level, 0);
        EXPECT_EQ(root.x + root.y + root.z, 0);
        EXPECT_TRUE(octree.cell_box(root).contains(scene.geometry().bounds()));
        const Vec3f extent = octree.cell_box(root).extent();
        EXPECT_EQ(extent.x, extent.y);  // a cube
        EXPECT_EQ(extent.y, extent.z);

        std::vector<int> parents(octree.cells.size(), 0);
        for (std::size_t i = 0; i < octree.cells.size(); ++i) {
            const OctreeCell& parent = octree.cells[i];
            if (parent.is_leaf()) continue;
            EXPECT_EQ(parent.ref_count(), 0u) << "inner cell " << i;
            ASSERT_LE(parent.first_child + 8u, octree.cells.size());
            ASSERT_GT(parent.first_child, i);
            const Box3f parent_box = octree.cell_box(parent);
            for (std::uint32_t c = 0; c < 8; ++c) {
                const OctreeCell& child = octree.cells[parent.first_child + c];
                ++parents[parent.first_child + c];
                EXPECT_EQ(child.level, parent.level + 1);
                const Box3f child_box = octree.cell_box(child);
                for (int axis = 0; axis < 3; ++axis) {
                    const std::uint32_t bit = (c >> axis) & 1u;
                    EXPECT_EQ(child.coordinate(axis), 2 * parent.coordinate(axis) + bit);
                    // The octant: the lower or upper half of the parent, split at its mid plane.
                    const float mid = octree.cube.plane(axis, child.level, 2 * parent.coordinate(axis) + 1);
                    EXPECT_LT(parent_box.lo[axis], mid);
                    EXPECT_LT(mid, parent_box.hi[axis]);
                    EXPECT_EQ(child_box.lo[axis], bit ? mid : parent_box.lo[axis])
                        << "cell " << i << " child " << c;
                    EXPECT_EQ(child_box.hi[axis], bit ? parent_box.hi[axis] : mid)
                        << "cell " << i << " child " << c;
                }
            }
        }
        for (std::size_t i = 1; i < parents.size(); ++i)
            ASSERT_EQ(parents[i], 1) << "cell " << i << " must have exactly one parent";
    }
}

TEST(OctreeBuild, EveryPrimitiveIsReferencedInEveryLeafItOverlaps) {
    for (const TestScene& scene : {sphere_and_spheres(), triangle_soup()}) {
        const Geometry geometry = scene.geometry();
        const Octree octree = build_octree(geometry, octree_options(6, 4));
        for (std::size_t i = 0; i < octree.cells.size(); ++i) {
            const OctreeCell& leaf = octree.cells[i];
            if (!leaf.is_leaf()) continue;
            const Box3f box = octree.cell_box(leaf);
            const auto begin = octree.references.begin() + leaf.ref_begin;
            const auto end = octree.references.begin() + leaf.ref_end;
            ASSERT_TRUE(std::is_sorted(begin, end));
            ASSERT_EQ(std::adjacent_find(begin, end), end) << "duplicate reference in leaf " << i;
            for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
                const bool referenced = std::binary_search(begin, end, prim);
                if (primitive_overlaps_box(geometry, prim, box)) {
                    ASSERT_TRUE(referenced) << "primitive " << prim << " overlaps leaf " << i;
                }
                // And nothing else: a reference is a primitive overlapping the cell grown by the tolerance.
                if (referenced) {
                    ASSERT_TRUE(primitive_overlaps_box(geometry, prim, octree.reference_box(box)));
                }
            }
        }
    }
}

TEST(OctreeBuild, DepthAndLeafSizeFollowTheOptions) {
    for (const TestScene& scene : {sphere_and_spheres(), triangle_soup(), coincident_triangles()}) {
        for (const auto& [max_depth, leaf_size] : {std::pair{3, 8}, std::pair{6, 1}, std::pair{10, 8}}) {
            const Octree octree = build_octree(scene.geometry(), octree_options(max_depth, leaf_size));
            EXPECT_EQ(octree.max_depth, max_depth);
            for (const OctreeCell& cell : octree.cells) {
                ASSERT_LE(cell.level, max_depth);
                if (!cell.is_leaf() || cell.ref_count() <= static_cast<std::uint32_t>(leaf_size)) continue;
                if (cell.level == max_depth) continue;
                // Over-full above max depth: only when the split would separate nothing.
                const std::span<const std::uint32_t> references(octree.references.data() + cell.ref_begin,
                                                                cell.ref_count());
                EXPECT_TRUE(split_separates_nothing(
                    split_references(scene.geometry(), octree, cell, references), cell.ref_count()))
                    << "leaf at level " << int(cell.level) << " with " << cell.ref_count() << " references";
            }
        }
    }
    // Options beyond the supported range are clamped. Nine points in one spot zoom down as deep as allowed.
    std::vector<Sphere> cluster(9, Sphere{{0.3f, 0.3f, 0.3f}, 0.0f, 0});
    cluster.push_back({{0, 0, 0}, 0.01f, 0});
    cluster.push_back({{1, 1, 1}, 0.01f, 0});
    const Octree deepest = build_octree({{}, cluster}, octree_options(99, 8));
    EXPECT_EQ(deepest.max_depth, kOctreeMaxLevel);
    for (const OctreeCell& cell : deepest.cells)
        ASSERT_LE(cell.level, kOctreeMaxLevel);
    EXPECT_GT(deepest.cells.size(), 8u * 8u);
    const Octree shallowest = build_octree({{}, cluster}, octree_options(-3, 1));
    EXPECT_EQ(shallowest.max_depth, 0);
    EXPECT_EQ(shallowest.cells.size(), 1u);
}

TEST(OctreeBuild, CoincidentTrianglesDoNotExplode) {
    const TestScene scene = coincident_triangles();
    const Octree octree = build_octree(scene.geometry(), octree_options(10, 8));
    // A split is refused once the children that are not empty all keep the 3000 references: a few leaves
    // hold them. Splitting to max depth would copy the 3000 into every cell along the triangle (~1e5 cells).
    EXPECT_LT(octree.references.size(), 20u * scene.triangles.size());
    EXPECT_LT(octree.cells.size(), 1000u);
    const auto full_leaves = std::count_if(octree.cells.begin(), octree.cells.end(), [](const OctreeCell& c) {
        return c.is_leaf() && c.ref_count() >= 3000;
    });
    EXPECT_GE(full_leaves, 1);
}

TEST(OctreeBuild, CellsFarFromTheOriginStayWiderThanTheTolerance) {
    // A sphere of radius 50 a million units out: the tolerance is about 1 (2^-20 of 1e6), and level-10
    // cells of its 100-wide root would be a tenth of that.
    TestScene far;
    make_icosphere(3, {1e6f, -1e6f, 1e6f}, 50.0f).append_triangles(far.triangles);
    const Octree octree = build_octree(far.geometry(), octree_options(10, 8));
    ASSERT_GT(octree.tolerance, 0.5f);
    EXPECT_EQ(octree.max_depth, deepest_separating_level(octree.cube, octree.tolerance, 10));
    EXPECT_LT(octree.max_depth, 10);
    for (const OctreeCell& cell : octree.cells) {
        const Box3f box = octree.cell_box(cell);
        ASSERT_GE(box.extent().x, kSmallestCellInTolerances * octree.tolerance) << int(cell.level);
    }
    // The level is the deepest of such cells: one level further they would be narrower.
    EXPECT_LT(octree.cube.size * inverse_power_of_two(octree.max_depth + 1),
              kSmallestCellInTolerances * octree.tolerance);
    // Each triangle is referenced by a few cells, not by the thousands that a depth of 10 gave.
    EXPECT_LT(octree.references.size(), 20u * far.triangles.size());
    // The same scene at the origin: the tolerance is tiny and the options alone decide.
    TestScene near;
    make_icosphere(3, {0, 0, 0}, 50.0f).append_triangles(near.triangles);
    EXPECT_EQ(build_octree(near.geometry(), octree_options(10, 8)).max_depth, 10);
}

TEST(OctreeBuild, DegenerateScenes) {
    const Octree empty = build_octree({}, {});
    ASSERT_EQ(empty.cells.size(), 1u);
    EXPECT_EQ(empty.cells[0].ref_count(), 0u);
    const std::vector<Sphere> point{{{1, 2, 3}, 0.0f, 0}};
    const Octree single_point = build_octree({{}, point}, {});
    ASSERT_EQ(single_point.cells.size(), 1u);
    EXPECT_EQ(single_point.cells[0].ref_count(), 1u);
}

// ---------------------------------------------------------------------------------------------------------
// Revelles' tables

// The parameters of a node [0, 1]^3 (mid planes 0.5) in the mirrored frame, and the real children the
// tables visit, in order.
std::vector<int> children_by_tables(const Vec3f& origin, const Vec3f& direction) {
    Vec3f t0, t1, tm;
    int mirror = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const bool mirrored = direction[axis] < 0.0f;
        const float inv = direction[axis] == 0.0f ? kInfinity : 1.0f / direction[axis];
        mirror |= mirrored ? 1 << axis : 0;
        t0[axis] = ((mirrored ? 1.0f : 0.0f) - origin[axis]) * inv;
        t1[axis] = ((mirrored ? 0.0f : 1.0f) - origin[axis]) * inv;
        tm[axis] = (0.5f - origin[axis]) * inv;
    }
    std::vector<int> children;
    if (!(max_component(t0) < std::min({t1.x, t1.y, t1.z}))) return children;
    for (int c = revelles::first_child(t0, tm); c != revelles::kExitParent;
         c = revelles::next_child(c, tm, t1)) {
        children.push_back(c ^ mirror);
        if (children.size() > 8) break;
    }
    return children;
}

// The children the line crosses (interval of positive length), by slab tests on each octant, by entry.
std::vector<int> children_by_slabs(const Vec3f& origin, const Vec3f& direction) {
    std::vector<std::pair<float, int>> crossed;
    for (int c = 0; c < 8; ++c) {
        float entry = -kInfinity, exit = kInfinity;
        for (int axis = 0; axis < 3; ++axis) {
            const float lo = (c >> axis) & 1 ? 0.5f : 0.0f, hi = lo + 0.5f;
            if (direction[axis] == 0.0f) {
                if (origin[axis] < lo || origin[axis] > hi) entry = kInfinity;
                continue;
            }
            const float a = (lo - origin[axis]) / direction[axis], b = (hi - origin[axis]) / direction[axis];
            entry = std::max(entry, std::min(a, b));
            exit = std::min(exit, std::max(a, b));
        }
        if (entry < exit) crossed.push_back({entry, c});
    }
    std::sort(crossed.begin(), crossed.end());
    std::vector<int> children;
    for (const auto& [entry, c] : crossed)
        children.push_back(c);
    return children;
}

TEST(OctreeRevelles, FirstAndNextChildFollowTheSlabOrder) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> coordinate(-1.0f, 2.0f);
    std::normal_distribution<float> gaussian;
    int crossing = 0, with_four = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec3f origin(coordinate(rng), coordinate(rng), coordinate(rng));
        Vec3f direction(gaussian(rng), gaussian(rng), gaussian(rng));
        if (i % 4 == 1) direction[i % 3] = 0.0f;  // a zero component: t = +-inf, tm = +-inf
        if (i % 8 == 3) direction[(i + 1) % 3] = -0.0f;
        const std::vector<int> by_tables = children_by_tables(origin, direction);
        ASSERT_EQ(by_tables, children_by_slabs(origin, direction))
            << "ray " << i << " o=(" << origin.x << ", " << origin.y << ", " << origin.z << ") d=("
            << direction.x << ", " << direction.y << ", " << direction.z << ")";
        crossing += by_tables.empty() ? 0 : 1;
        with_four += by_tables.size() == 4 ? 1 : 0;
    }
    // The rays exercise the tables: most cross the node, some through the maximum of 4 octants.
    EXPECT_GT(crossing, 2000);
    EXPECT_GT(with_four, 100);
}

TEST(OctreeRevelles, TiesStayInsideTheParent) {
    // Exit parameters tie between leaving the parent (x, child 1 is upper in x) and moving to child 3 (y):
    // the move inside wins, so the grazed child is visited.
    EXPECT_EQ(revelles::next_child(1, {0.5f, 1.0f, 2.0f}, {1.0f, 2.0f, 3.0f}), 3);
    EXPECT_EQ(revelles::next_child(1, {0.5f, 1.5f, 2.0f}, {1.0f, 2.0f, 3.0f}), revelles::kExitParent);
    // Entry plane x; the ray has crossed the y mid plane but not the z one.
    EXPECT_EQ(revelles::first_child({1.0f, 0.0f, 0.0f}, {2.0f, 0.5f, 3.0f}), 2);
}

// ---------------------------------------------------------------------------------------------------------
// The walk

// Leaf (cell index) intervals along the ray by slab tests on every leaf, with the walk's own plane
// coordinates and parameter formula: the leaves whose interval has positive length and meets
// [tnear, tfar], by entry. The walk grows the root by the geometric tolerance, so a leaf's faces on the
// root's faces are moved out by it.
std::vector<std::uint32_t> leaves_by_slabs(const Octree& octree, const Ray& ray) {
    const Box3f root = octree.cell_box(octree.cells[0]);
    std::vector<std::tuple<float, float, std::uint32_t>> crossed;
    for (std::uint32_t i = 0; i < octree.cells.size(); ++i) {
        const OctreeCell& cell = octree.cells[i];
        if (!cell.is_leaf()) continue;
        Box3f box = octree.cell_box(cell);
        for (int axis = 0; axis < 3; ++axis) {
            if (box.lo[axis] == root.lo[axis]) box.lo[axis] -= octree.tolerance;
            if (box.hi[axis] == root.hi[axis]) box.hi[axis] += octree.tolerance;
        }
        float entry = -kInfinity, exit = kInfinity;
        for (int axis = 0; axis < 3; ++axis) {
            if (ray.direction[axis] == 0.0f) {
                if (ray.origin[axis] < box.lo[axis] || ray.origin[axis] > box.hi[axis]) entry = kInfinity;
                continue;
            }
            const float inv = 1.0f / ray.direction[axis];
            const float a = (box.lo[axis] - ray.origin[axis]) * inv,
                        b = (box.hi[axis] - ray.origin[axis]) * inv;
            entry = std::max(entry, std::min(a, b));
            exit = std::min(exit, std::max(a, b));
        }
        if (entry < exit && entry <= ray.tfar && exit >= ray.tnear) crossed.emplace_back(entry, exit, i);
    }
    return testing::in_order_of_entry(std::move(crossed));
}

TEST(OctreeAccel, VisitsTheLeavesItCrossesInOrderOfEntry) {
    std::size_t compared = 0, longest = 0;
    for (const TestScene& scene : {sphere_and_spheres(), triangle_soup()}) {
        for (const OctreeOptions options :
             {octree_options(10, 8), octree_options(5, 1), octree_options(1, 1)}) {
            OctreeAccel accel;
            accel.build(scene.geometry(), build_options_with(options));
            const Octree octree = build_octree(scene.geometry(), options);  // same cells, same indices
            const Box3f bounds = scene.geometry().bounds();
            std::vector<Ray> rays = testing::random_rays(bounds, 1500, 21).rays;
            const std::vector<Ray> axis = testing::axis_parallel_rays(bounds, 600, 22).rays;
            const std::vector<Ray> clipped = testing::clipped_rays(bounds, 600, 23).rays;
            rays.insert(rays.end(), axis.begin(), axis.end());
            rays.insert(rays.end(), clipped.begin(), clipped.end());
            for (std::size_t i = 0; i < rays.size(); ++i) {
                const std::vector<std::uint32_t> expected = leaves_by_slabs(octree, rays[i]);
                ASSERT_EQ(accel.leaves_along(rays[i]), expected) << "ray " << i;
                ++compared;
                longest = std::max(longest, expected.size());
            }
        }
    }
    EXPECT_GT(longest, 20u);  // the rays do cross many leaves
    EXPECT_GT(compared, 10000u);
}

// Rays with zero direction components whose origins lie exactly on cell planes: the NaN case of Revelles'
// parameters (0 * inf), inner mid planes and root faces alike. Every point of the ray inside the root lies in
// a leaf the walk visits, and the answers agree with brute force.
TEST(OctreeAccel, RaysInCellPlanes) {
    const TestScene scene = sphere_and_spheres();
    const Geometry geometry = scene.geometry();
    const OctreeOptions options = octree_options(6, 2);
    const Octree octree = build_octree(geometry, options);
    const std::vector<Ray> rays = testing::cell_plane_rays(octree, 3000, 3);
    const Box3f root = octree.cell_box(octree.cells[0]);
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        OctreeAccel accel;
        accel.build(geometry, build_options_with(options, test));
        testing::expect_brute_force_answers(accel, geometry, test, rays, 200);
    }
    OctreeAccel accel;
    accel.build(geometry, build_options_with(options));
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const std::vector<std::uint32_t> leaves = accel.leaves_along(rays[i]);
        for (float t = 0.0f; t < 2.0f * root.extent().x; t += 0.05f * root.extent().x) {
            const Vec3f p = rays[i].origin + t * rays[i].direction;
            if (!root.contains(p)) continue;
            ASSERT_TRUE(std::any_of(
                leaves.begin(), leaves.end(),
                [&](std::uint32_t leaf) { return octree.cell_box(octree.cells[leaf]).contains(p); }))
                << "ray " << i << " point at t = " << t << " is in no visited leaf";
        }
    }
}

// A primitive spanning several leaves is tested in the first and hit beyond that leaf's exit; a closer hit in
// a later leaf must still be found.
TEST(OctreeAccel, AHitBeyondTheLeafExitDoesNotEndTheWalk) {
    const testing::HitBeyondLeafExit example;
    const TestScene& scene = example.scene;
    const Ray& ray = example.ray;
    const OctreeOptions options = octree_options(6, 1);
    OctreeAccel accel;
    accel.build(scene.geometry(), build_options_with(options));

    // The set-up: the first leaf entered holds A but not B, and A's hit lies beyond that leaf's exit.
    const Octree octree = build_octree(scene.geometry(), options);
    const std::vector<std::uint32_t> leaves = accel.leaves_along(ray);
    ASSERT_FALSE(leaves.empty());
    const OctreeCell& first = octree.cells[leaves.front()];
    const std::span<const std::uint32_t> refs(octree.references.data() + first.ref_begin, first.ref_count());
    ASSERT_EQ(std::vector<std::uint32_t>(refs.begin(), refs.end()), std::vector<std::uint32_t>{0});
    ASSERT_LT(octree.cell_box(first).hi.x, 3.0f);

    std::vector<Hit> hits(1);
    accel.intersect({&ray, 1}, hits);
    EXPECT_EQ(hits[0].prim, 1);
    EXPECT_FLOAT_EQ(hits[0].t, 4.0f);
}

TEST(OctreeAccel, StopsOnceTheClosestHitLiesBeforeTheNextLeaf) {
    const TestScene scene = sphere_and_spheres();
    OctreeAccel accel;
    accel.build(scene.geometry(), build_options_with(octree_options(8, 2)));
    // Through the icosphere's centre: the hit is on its near side, and half of the leaves are beyond it.
    const Ray ray{{0.2f, -0.1f, -5.0f}, {0.01f, 0.02f, 1.0f}, 0.0f, kInfinity};
    std::vector<Hit> hits(1);
    TraversalCounters counters;
    accel.intersect({&ray, 1}, hits, &counters);
    ASSERT_TRUE(hits[0].hit());
    EXPECT_LT(hits[0].prim, 1280);
    const std::size_t leaves = accel.leaves_along(ray).size();
    EXPECT_GT(leaves, 10u);
    EXPECT_LT(counters.nodes_visited, leaves);  // inner nodes included, fewer than the leaves along the ray
}

TEST(OctreeAccel, MaxDepthZeroIsOneLeafThatAgreesWithBruteForce) {
    for (const TestScene& scene : {sphere_and_spheres(), triangle_soup()}) {
        const Geometry geometry = scene.geometry();
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            OctreeAccel accel;
            accel.build(geometry, build_options_with(octree_options(0, 8), test));
            const AccelStats stats = accel.stats();
            EXPECT_EQ(stats.count("nodes"), 1u);
            EXPECT_EQ(stats.count("leaves"), 1u);
            EXPECT_EQ(stats.count("references"), geometry.size());
            BruteAccel brute;
            brute.build(geometry, build_options(test));
            const Box3f bounds = geometry.bounds();
            for (const testing::RaySet& set :
                 {testing::random_rays(bounds, 2000, 31), testing::axis_parallel_rays(bounds, 1000, 32),
                  testing::clipped_rays(bounds, 1000, 33), testing::hostile_rays(bounds)}) {
                std::vector<Hit> expected(set.rays.size()), hits(set.rays.size());
                std::vector<std::uint8_t> occluded(set.rays.size());
                brute.intersect(set.rays, expected);
                accel.intersect(set.rays, hits);
                accel.occluded(set.rays, occluded);
                EXPECT_EQ(compare_hits(set.rays, expected, hits).mismatches, 0u) << set.name;
                EXPECT_EQ(compare_occlusion(set.rays, expected, occluded).mismatches, 0u) << set.name;
            }
        }
    }
}

TEST(OctreeAccel, StatsMatchTheArrays) {
    for (const TestScene& scene : {sphere_and_spheres(), triangle_soup(), coincident_triangles()}) {
        const OctreeOptions options = octree_options(7, 4);
        OctreeAccel accel;
        accel.build(scene.geometry(), build_options_with(options));
        const Octree octree = build_octree(scene.geometry(), options);
        const AccelStats stats = accel.stats();
        std::size_t leaves = 0, empty = 0, references = 0, max_refs = 0, depth_sum = 0;
        int max_depth = 0;
        double sah = 0.0;  // unit costs, areas relative to the root cube's
        for (const OctreeCell& cell : octree.cells) {
            const double area_ratio = std::pow(0.25, cell.level);
            sah += area_ratio * (cell.is_leaf() ? cell.ref_count() : 1.0);
            if (!cell.is_leaf()) continue;
            ++leaves;
            empty += cell.ref_count() == 0 ? 1 : 0;
            references += cell.ref_count();
            max_refs = std::max<std::size_t>(max_refs, cell.ref_count());
            depth_sum += cell.level;
            max_depth = std::max<int>(max_depth, cell.level);
        }
        EXPECT_EQ(stats.primitives, scene.geometry().size());
        EXPECT_EQ(stats.count("nodes"), octree.cells.size());
        EXPECT_EQ(stats.count("leaves"), leaves);
        EXPECT_EQ(stats.count("empty_leaves"), empty);
        EXPECT_EQ(stats.count("references"), octree.references.size());
        EXPECT_EQ(stats.count("references"), references);
        EXPECT_EQ(stats.count("max_refs_per_leaf"), max_refs);
        EXPECT_EQ(stats.value("max_depth"), max_depth);
        EXPECT_DOUBLE_EQ(stats.value("mean_depth"),
                         static_cast<double>(depth_sum) / static_cast<double>(leaves));
        EXPECT_DOUBLE_EQ(stats.value("mean_refs_per_leaf"),
                         static_cast<double>(references) / static_cast<double>(leaves - empty));
        EXPECT_NEAR(stats.value("sah_cost"), sah, 1e-9 * sah);
        // An octree cell is a leaf or has eight children: every cell but the root is one of eight siblings.
        EXPECT_EQ(stats.count("nodes"), 1 + 8 * (stats.count("nodes") - leaves));
        std::size_t bytes = 0;
        for (const auto& [name, size] : stats.memory_by_array)
            bytes += size;
        EXPECT_EQ(accel.memory_bytes(), bytes);
        EXPECT_EQ(bytes, octree.cells.size() * sizeof(OctreeNode) +
                             octree.references.size() * sizeof(std::uint32_t));
    }
}

TEST(OctreeAccel, DeterministicBuild) {
    const TestScene scene = triangle_soup();
    const Octree a = build_octree(scene.geometry(), {});
    const Octree b = build_octree(scene.geometry(), {});
    ASSERT_EQ(a.cells.size(), b.cells.size());
    EXPECT_EQ(a.references, b.references);
    for (std::size_t i = 0; i < a.cells.size(); ++i) {
        ASSERT_EQ(a.cells[i].first_child, b.cells[i].first_child);
        ASSERT_EQ(a.cells[i].ref_begin, b.cells[i].ref_begin);
        ASSERT_EQ(a.cells[i].ref_end, b.cells[i].ref_end);
    }
}

}  // namespace
}  // namespace lancer
