// The SAH kd-tree: structural invariants (every primitive point lies in a leaf that references it, leaves
// reference only what reaches them, stats match the arrays, depth bounded), the event sweep against a naive
// O(N^2) SAH search at the root, the seed-003 cost model against brute force, termination on coincident
// triangles, and O(N log N) build time.
#include "accel/kdtree.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "accel/brute.hpp"
#include "accel/build_util.hpp"
#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::TestScene;

TestScene mixed_scene() {
    TestScene scene{"icosphere, knot and spheres", {}, {}};
    make_icosphere(2, {0, 0, 0}, 1.0f).append_triangles(scene.triangles);
    make_torus_knot(200, 8).append_triangles(scene.triangles);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (int i = 0; i < 20; ++i)
        scene.spheres.push_back({Vec3f(unit(rng), unit(rng), unit(rng)) * 4.0f - Vec3f(2.0f), 0.1f, 0});
    return scene;
}

TestScene soup_scene(int count, std::uint32_t seed) {
    TestScene scene{"random triangle soup", {}, {}};
    std::mt19937 rng(seed);
    testing::append_triangle_soup(rng, count, 10.0f, 10, 3.0f, 0.5f, scene.triangles);
    return scene;
}

// Axis-aligned squares on a few shared planes: planar primitives for the sweep and the classification.
TestScene planar_scene() {
    TestScene scene{"axis-aligned squares", {}, {}};
    for (int i = 0; i < 6; ++i) {
        const float x = static_cast<float>(i % 3), y = static_cast<float>(i);
        scene.triangles.push_back({{x, y, 0}, {x, y + 1, 0}, {x, y, 1}});      // in the plane x = const
        scene.triangles.push_back({{x, y, 2}, {x + 1, y, 2}, {x, y + 1, 2}});  // in the plane z = 2
        scene.triangles.push_back({{x, 1.5f, y}, {x + 1, 1.5f, y}, {x, 1.5f, y + 1}});  // y = 1.5
    }
    return scene;
}

// Closed axis-aligned cubes on a half-unit lattice: every face planar, many faces sharing a plane.
TestScene cubes_scene(int count, std::uint32_t seed) {
    TestScene scene{"cubes on a lattice", {}, {}};
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> cell(0, 12), size(1, 3);
    for (int i = 0; i < count; ++i) {
        const Vec3f lo(0.5f * static_cast<float>(cell(rng)), 0.5f * static_cast<float>(cell(rng)),
                       0.5f * static_cast<float>(cell(rng)));
        const Vec3f hi = lo + Vec3f(0.5f * static_cast<float>(size(rng)));
        for (int axis = 0; axis < 3; ++axis) {
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            for (float plane : {lo[axis], hi[axis]}) {
                Vec3f a, b, c, d;
                a[axis] = b[axis] = c[axis] = d[axis] = plane;
                a[u] = lo[u], a[v] = lo[v];
                b[u] = hi[u], b[v] = lo[v];
                c[u] = hi[u], c[v] = hi[v];
                d[u] = lo[u], d[v] = hi[v];
                scene.triangles.push_back({a, b, c});
                scene.triangles.push_back({a, c, d});
            }
        }
    }
    return scene;
}

TestScene coincident_scene() {
    TestScene scene{"thousands of coincident triangles", {}, {}};
    scene.triangles.assign(3000, Triangle{{0, 0, 0}, {1, 0, 0.5f}, {0, 1, 1}});
    scene.triangles.push_back({{-1, -1, 2}, {2, -1, 2}, {-1, 2, 2}});
    return scene;
}

BuildOptions with_cost(KdTreeCost cost, int max_depth = 0) {
    BuildOptions options;
    options.group<KdTreeOptions>().cost = cost;
    options.group<KdTreeOptions>().max_depth = max_depth;
    return options;
}

struct LeafView {
    const KdNode* node;
    Box3f box;
    int depth;
};

// The leaves with their boxes, from the layout alone: below child at index + 1, above child by index.
std::vector<LeafView> collect_leaves(const KdTreeData& tree) {
    std::vector<LeafView> leaves;
    auto visit = [&](auto&& self, std::uint32_t index, const Box3f& box, int depth) -> void {
        const KdNode& node = tree.nodes.at(index);
        if (node.is_leaf()) {
            leaves.push_back({&node, box, depth});
            return;
        }
        const int axis = node.axis();
        EXPECT_LT(box.lo[axis], node.split()) << "split on or outside its node, node " << index;
        EXPECT_GT(box.hi[axis], node.split()) << "split on or outside its node, node " << index;
        EXPECT_GT(node.above_child(), index + 1);
        Box3f below = box, above = box;
        below.hi[axis] = node.split();
        above.lo[axis] = node.split();
        self(self, index + 1, below, depth + 1);
        self(self, node.above_child(), above, depth + 1);
    };
    visit(visit, 0, tree.bounds, 0);
    return leaves;
}

// Points of a primitive: the vertices, edge midpoints and a grid of interior points of a triangle, or points
// spread over a sphere.
std::vector<Vec3f> sample_points(const Geometry& geometry, std::uint32_t prim) {
    std::vector<Vec3f> points;
    if (prim < geometry.triangles.size()) {
        const Triangle& tri = geometry.triangles[prim];
        constexpr int kSteps = 6;
        for (int i = 0; i <= kSteps; ++i) {
            for (int j = 0; i + j <= kSteps; ++j) {
                const float a = static_cast<float>(i) / kSteps, b = static_cast<float>(j) / kSteps;
                points.push_back(tri.v0 + a * (tri.v1 - tri.v0) + b * (tri.v2 - tri.v0));
            }
        }
    } else {
        const Sphere& sphere = geometry.spheres[prim - geometry.triangles.size()];
        for (int i = 0; i < 3; ++i) {
            for (float sign : {-1.0f, 1.0f}) {
                Vec3f p = sphere.center;
                p[i] += sign * sphere.radius;
                points.push_back(p);
            }
        }
        points.push_back(sphere.center + Vec3f(sphere.radius * 0.57735f));
    }
    return points;
}

bool contains_with_margin(const Box3f& box, Vec3f p, float margin) {
    return p.x >= box.lo.x - margin && p.y >= box.lo.y - margin && p.z >= box.lo.z - margin &&
           p.x <= box.hi.x + margin && p.y <= box.hi.y + margin && p.z <= box.hi.z + margin;
}

// The invariants every build must satisfy, whatever the options.
void expect_valid_tree(const KdTreeAccel& accel, const Geometry& geometry) {
    const KdTreeData& tree = accel.tree();
    const std::vector<LeafView> leaves = collect_leaves(tree);
    std::size_t empty = 0, references = 0, max_refs = 0, reference_slots = 0;
    int max_depth = 0;
    double depth_sum = 0.0;
    std::vector<std::vector<std::size_t>> leaves_of(geometry.size());
    for (std::size_t l = 0; l < leaves.size(); ++l) {
        const LeafView& leaf = leaves[l];
        const std::span<const std::uint32_t> prims = tree.leaf_primitives(*leaf.node);
        empty += prims.empty() ? 1 : 0;
        references += prims.size();
        reference_slots += prims.size() > 1 ? prims.size() : 0;
        max_refs = std::max(max_refs, prims.size());
        max_depth = std::max(max_depth, leaf.depth);
        depth_sum += leaf.depth;
        for (std::uint32_t prim : prims) {
            ASSERT_LT(prim, geometry.size());
            leaves_of[prim].push_back(l);
            // The leaf holds only primitives that reach it: their clipped part is in the leaf's box.
            const Box3f part = clipped_primitive_bounds(geometry, prim, leaf.box);
            EXPECT_FALSE(part.empty()) << "primitive " << prim << " does not reach its leaf";
            EXPECT_TRUE(leaf.box.contains(part.lo) && leaf.box.contains(part.hi));
            EXPECT_TRUE(primitive_overlaps_box(geometry, prim, leaf.box)) << "primitive " << prim;
        }
    }
    // Every point of every primitive lies in (the tolerance of) a leaf that references it.
    for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
        for (const Vec3f& p : sample_points(geometry, prim)) {
            const bool covered = std::any_of(
                leaves_of[prim].begin(), leaves_of[prim].end(),
                [&](std::size_t l) { return contains_with_margin(leaves[l].box, p, tree.tolerance); });
            ASSERT_TRUE(covered) << "a point of primitive " << prim << " is in no leaf referencing it";
        }
    }
    EXPECT_EQ(reference_slots, tree.references.size());
    EXPECT_LE(max_depth, tree.depth_limit);
    EXPECT_LE(tree.depth_limit, kKdTreeMaxDepth);

    const AccelStats stats = accel.stats();
    EXPECT_EQ(stats.primitives, geometry.size());
    EXPECT_EQ(stats.count("nodes"), tree.nodes.size());
    EXPECT_EQ(stats.count("leaves"), leaves.size());
    EXPECT_EQ(stats.count("nodes"), 2 * stats.count("leaves") - 1);  // a full binary tree
    EXPECT_EQ(stats.count("empty_leaves"), empty);
    EXPECT_EQ(stats.count("references"), references);
    EXPECT_EQ(stats.count("max_refs_per_leaf"), max_refs);
    EXPECT_EQ(stats.value("max_depth"), max_depth);
    EXPECT_DOUBLE_EQ(stats.value("mean_depth"), depth_sum / static_cast<double>(leaves.size()));
    if (leaves.size() > empty) {
        EXPECT_DOUBLE_EQ(stats.value("mean_refs_per_leaf"),
                         static_cast<double>(references) / static_cast<double>(leaves.size() - empty));
    }
    EXPECT_GT(stats.value("sah_cost"), 0.0);
    std::size_t listed = 0;
    for (const auto& [name, bytes] : stats.memory_by_array)
        listed += bytes;
    EXPECT_EQ(listed, accel.memory_bytes());
    EXPECT_EQ(accel.memory_bytes(),
              tree.nodes.size() * sizeof(KdNode) + tree.references.size() * sizeof(std::uint32_t));
}

TEST(KdTree, NodeLayoutRoundTrips) {
    const KdNode inner = KdNode::inner(2, -1.5f, 12345);
    EXPECT_FALSE(inner.is_leaf());
    EXPECT_EQ(inner.axis(), 2);
    EXPECT_EQ(inner.split(), -1.5f);
    EXPECT_EQ(inner.above_child(), 12345u);
    const KdNode one = KdNode::leaf(1, 77);
    const std::uint32_t references[] = {5, 6, 7};
    EXPECT_TRUE(one.is_leaf());
    EXPECT_EQ(one.primitive_count(), 1u);
    EXPECT_EQ(*one.primitives(references), 77u);  // inline
    const KdNode many = KdNode::leaf(2, 1);
    EXPECT_EQ(many.primitives(references)[0], 6u);
    EXPECT_EQ(many.primitives(references)[1], 7u);
    const KdNode largest = KdNode::leaf(KdNode::kMaxField, 0);
    EXPECT_TRUE(largest.is_leaf());
    EXPECT_EQ(largest.primitive_count(), KdNode::kMaxField);
}

TEST(KdTree, StructuralInvariantsOnSeveralScenes) {
    for (const TestScene& scene : {mixed_scene(), soup_scene(1500, 3), planar_scene(), coincident_scene()}) {
        for (KdTreeCost cost : {KdTreeCost::WaldHavran, KdTreeCost::Seed003}) {
            SCOPED_TRACE(scene.name +
                         (cost == KdTreeCost::Seed003 ? ", Ferreira & Mendoza" : ", Wald-Havran"));
            KdTreeAccel accel;
            accel.build(scene.geometry(), with_cost(cost));
            expect_valid_tree(accel, scene.geometry());
            if (scene.triangles.size() > 100) {
                EXPECT_GT(accel.stats().count("leaves"), 1u);  // it did split
            }
        }
    }
}

TEST(KdTree, EmptySceneIsOneEmptyLeaf) {
    KdTreeAccel accel;
    accel.build({}, {});
    const AccelStats stats = accel.stats();
    EXPECT_EQ(stats.count("nodes"), 1u);
    EXPECT_EQ(stats.count("leaves"), 1u);
    EXPECT_EQ(stats.count("empty_leaves"), 1u);
    EXPECT_EQ(stats.count("references"), 0u);
    const std::vector<Ray> rays = {{{0, 0, -1}, {0, 0, 1}, 0.0f, kInfinity}};
    std::vector<Hit> hits(1);
    accel.intersect(rays, hits);
    EXPECT_FALSE(hits[0].hit());
}

// The naive SAH evaluation (seeds 002 and 004, Wald & Havran): for each axis and each candidate
// plane from the primitives' bounds, count the primitives left of, right of and in the plane one by one and
// evaluate the cost, the planar ones on their cheaper side.
struct NaiveSah {
    const Geometry& geometry;
    KdTreeOptions options;
    Box3f box;

    [[nodiscard]] static double area_of(const Box3f& b) {
        const double x = double{b.hi.x} - b.lo.x, y = double{b.hi.y} - b.lo.y, z = double{b.hi.z} - b.lo.z;
        return 2.0 * (x * y + y * z + z * x);
    }

    [[nodiscard]] double cost(std::size_t left, std::size_t right, double left_area,
                              double right_area) const {
        const double area = area_of(box);
        const double weighted =
            (left_area * static_cast<double>(left) + right_area * static_cast<double>(right)) / area;
        if (options.cost == KdTreeCost::Seed003) return weighted;
        const double factor = left == 0 || right == 0 ? 1.0 - options.empty_bonus : 1.0;
        return options.traversal_cost + options.intersection_cost * weighted * factor;
    }

    [[nodiscard]] double cost_at(int axis, float plane) const {
        std::size_t left = 0, right = 0, planar = 0;
        for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
            const Box3f bounds = clipped_primitive_bounds(geometry, prim, box);
            const float lo = bounds.lo[axis], hi = bounds.hi[axis];
            if (lo == hi) {  // flat in this axis: in the plane, or wholly on one side
                planar += lo == plane ? 1 : 0;
                left += lo < plane ? 1 : 0;
                right += lo > plane ? 1 : 0;
            } else {  // straddling primitives count on both sides
                left += lo < plane ? 1 : 0;
                right += hi > plane ? 1 : 0;
            }
        }
        Box3f left_box = box, right_box = box;
        left_box.hi[axis] = plane;
        right_box.lo[axis] = plane;
        const double left_area = area_of(left_box), right_area = area_of(right_box);
        return std::min(cost(left + planar, right, left_area, right_area),
                        cost(left, right + planar, left_area, right_area));
    }

    [[nodiscard]] double minimum() const {
        double best = std::numeric_limits<double>::infinity();
        for (int axis = 0; axis < 3; ++axis) {
            for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
                const Box3f bounds = clipped_primitive_bounds(geometry, prim, box);
                for (float plane : {bounds.lo[axis], bounds.hi[axis]}) {
                    if (box.lo[axis] < plane && plane < box.hi[axis])
                        best = std::min(best, cost_at(axis, plane));
                }
            }
        }
        return best;
    }
};

TEST(KdTree, RootSplitHasTheMinimalCostOfANaiveSearch) {
    TestScene combined = soup_scene(150, 11);
    const TestScene planar = planar_scene();
    combined.triangles.insert(combined.triangles.end(), planar.triangles.begin(), planar.triangles.end());
    combined.spheres.push_back({{5, 5, 5}, 1.0f, 0});
    for (const TestScene& scene :
         {combined, planar, cubes_scene(4, 1), cubes_scene(12, 2), cubes_scene(30, 3), soup_scene(200, 4)}) {
        for (KdTreeCost cost : {KdTreeCost::WaldHavran, KdTreeCost::Seed003}) {
            SCOPED_TRACE(scene.name +
                         (cost == KdTreeCost::Seed003 ? ", Ferreira & Mendoza" : ", Wald-Havran"));
            KdTreeAccel accel;
            accel.build(scene.geometry(), with_cost(cost));
            const KdNode& root = accel.tree().nodes[0];
            ASSERT_FALSE(root.is_leaf());
            const NaiveSah naive{scene.geometry(), with_cost(cost).group<KdTreeOptions>(),
                                 accel.tree().bounds};
            const double chosen = naive.cost_at(root.axis(), root.split());
            const double minimum = naive.minimum();
            EXPECT_NEAR(chosen, minimum, 1e-9 * minimum) << "axis " << root.axis() << " at " << root.split();
            EXPECT_LT(minimum,
                      kdtree_leaf_cost(with_cost(cost).group<KdTreeOptions>(), scene.geometry().size()));
        }
    }
}

TEST(KdTree, Seed003CostAgreesWithBruteForce) {
    for (const TestScene& scene : {mixed_scene(), soup_scene(1500, 5), planar_scene(), coincident_scene()}) {
        const Box3f bounds = scene.geometry().bounds();
        const std::vector<testing::RaySet> sets = {
            testing::random_rays(bounds, 2000, 21), testing::vertex_and_edge_rays(scene.triangles, 2000, 22),
            testing::axis_parallel_rays(bounds, 2000, 23), testing::clipped_rays(bounds, 1000, 24),
            testing::hostile_rays(bounds)};
        for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            BuildOptions options = with_cost(KdTreeCost::Seed003);
            options.triangle_test = test;
            KdTreeAccel accel;
            accel.build(scene.geometry(), options);
            BruteAccel brute;
            brute.build(scene.geometry(), options);
            for (const testing::RaySet& set : sets) {
                std::vector<Hit> expected(set.rays.size()), hits(set.rays.size());
                brute.intersect(set.rays, expected);
                accel.intersect(set.rays, hits);
                const Agreement closest = compare_hits(set.rays, expected, hits);
                EXPECT_EQ(closest.mismatches, 0u)
                    << scene.name << ", " << set.name << ": " << closest.summary();
                std::vector<std::uint8_t> occluded(set.rays.size());
                accel.occluded(set.rays, occluded);
                const Agreement any = compare_occlusion(set.rays, expected, occluded);
                EXPECT_EQ(any.mismatches, 0u) << scene.name << ", " << set.name << ": " << any.summary();
            }
        }
    }
}

// Rays that start exactly on split planes of the built tree: lying in the plane (a zero direction
// component, the 0 * inf = NaN case), leaving it, and running along it with a second zero component.
TEST(KdTree, RaysOnSplitPlanesAgreeWithBruteForce) {
    for (const TestScene& scene : {cubes_scene(30, 7), mixed_scene(), soup_scene(1500, 8)}) {
        KdTreeAccel accel;
        accel.build(scene.geometry(), {});
        BruteAccel brute;
        brute.build(scene.geometry(), {});
        const KdTreeData& tree = accel.tree();
        std::mt19937 rng(12);
        std::uniform_real_distribution<float> unit(0.0f, 1.0f);
        std::vector<Ray> rays;
        for (const KdNode& node : tree.nodes) {
            if (node.is_leaf()) continue;
            const int axis = node.axis();
            for (int k = 0; k < 8; ++k) {
                Vec3f origin = tree.bounds.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * tree.bounds.extent();
                origin[axis] = node.split();
                Vec3f direction = Vec3f(unit(rng), unit(rng), unit(rng)) - Vec3f(0.5f);
                if (k % 2 == 0) direction[axis] = 0.0f;            // in the plane
                if (k % 4 == 0) direction[(axis + 1) % 3] = 0.0f;  // and along an axis
                if (k == 7)
                    direction = -(origin - tree.bounds.center());  // from the plane through the centre
                rays.push_back({origin, direction, 0.0f, kInfinity});
            }
            if (rays.size() > 4000) break;
        }
        std::vector<Hit> expected(rays.size()), hits(rays.size());
        brute.intersect(rays, expected);
        accel.intersect(rays, hits);
        const Agreement closest = compare_hits(rays, expected, hits);
        EXPECT_EQ(closest.mismatches, 0u) << scene.name << ": " << closest.summary();
        EXPECT_GT(closest.hits, rays.size() / 10);
        std::vector<std::uint8_t> occluded(rays.size());
        accel.occluded(rays, occluded);
        const Agreement any = compare_occlusion(rays, expected, occluded);
        EXPECT_EQ(any.mismatches, 0u) << scene.name << ": " << any.summary();
    }
}

TEST(KdTree, DepthStaysWithinTheLimit) {
    const TestScene scene = soup_scene(3000, 9);
    for (KdTreeCost cost : {KdTreeCost::WaldHavran, KdTreeCost::Seed003}) {
        KdTreeAccel automatic;
        automatic.build(scene.geometry(), with_cost(cost));
        const int expected_limit = 8 + static_cast<int>(1.3 * std::log2(3000.0));
        EXPECT_EQ(automatic.tree().depth_limit, expected_limit);
        EXPECT_LE(automatic.stats().value("max_depth"), expected_limit);

        KdTreeAccel shallow;
        shallow.build(scene.geometry(), with_cost(cost, 3));
        EXPECT_EQ(shallow.stats().value("max_depth"), 3);  // the limit binds here
        expect_valid_tree(shallow, scene.geometry());

        KdTreeAccel capped;
        capped.build(scene.geometry(), with_cost(cost, 1000));
        EXPECT_EQ(capped.tree().depth_limit, kKdTreeMaxDepth);
        EXPECT_LE(capped.stats().value("max_depth"), kKdTreeMaxDepth);
    }
    KdTreeAccel negative;
    EXPECT_THROW(negative.build(scene.geometry(), with_cost(KdTreeCost::WaldHavran, -1)),
                 std::invalid_argument);
}

TEST(KdTree, CoincidentTrianglesTerminateWithFewNodes) {
    const TestScene scene = coincident_scene();
    for (KdTreeCost cost : {KdTreeCost::WaldHavran, KdTreeCost::Seed003}) {
        KdTreeAccel accel;
        accel.build(scene.geometry(), with_cost(cost));
        const AccelStats stats = accel.stats();
        EXPECT_LE(stats.count("nodes"), 31u);
        EXPECT_LE(stats.count("references"),
                  3001u + 3000u);  // the 3000 copies are never split apart, at most once
        expect_valid_tree(accel, scene.geometry());
    }
}

TEST(KdTree, SameTreeEveryBuild) {
    const TestScene scene = mixed_scene();
    KdTreeAccel first, second;
    first.build(scene.geometry(), {});
    second.build(scene.geometry(), {});
    ASSERT_EQ(first.tree().nodes.size(), second.tree().nodes.size());
    ASSERT_EQ(first.tree().references, second.tree().references);
    for (std::size_t i = 0; i < first.tree().nodes.size(); ++i)
        ASSERT_EQ(std::memcmp(&first.tree().nodes[i], &second.tree().nodes[i], sizeof(KdNode)), 0);
}

}  // namespace
}  // namespace lancer
