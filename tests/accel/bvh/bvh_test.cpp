// The binary BVH: structural invariants of both builders, SAH optimality of the sweep at the root,
// determinism whatever the thread count, bounded depth on degenerate input; spatial splits that happen where
// they should, within their budget, and on the inputs that are hard on the cuts.
#include "accel/bvh/bvh.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <random>

#include "accel/build_util.hpp"
#include "accel/bvh/binned_builder.hpp"
#include "accel/bvh/build.hpp"
#include "accel/bvh/pair_partition.hpp"
#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::knot_triangles;

BuildOptions with_builder(BvhBuilder builder, int max_leaf_size = 4, bool spatial_splits = false) {
    BuildOptions options;
    options.group<BvhOptions>().builder = builder;
    options.group<BvhOptions>().max_leaf_size = max_leaf_size;
    options.group<BvhOptions>().spatial_splits = spatial_splits;
    return options;
}

BuildOptions with_spatial_splits(int max_leaf_size = 4) {
    return with_builder(BvhBuilder::BinnedSah, max_leaf_size, true);
}

// Points of a primitive: a triangle's vertices, the middles of its edges and its centroid; a sphere's poles.
std::vector<Vec3f> points_of(const Geometry& geometry, std::uint32_t prim) {
    if (prim < geometry.triangles.size()) {
        const Triangle& tri = geometry.triangles[prim];
        return {tri.v0,
                tri.v1,
                tri.v2,
                0.5f * (tri.v0 + tri.v1),
                0.5f * (tri.v1 + tri.v2),
                0.5f * (tri.v2 + tri.v0),
                (tri.v0 + tri.v1 + tri.v2) * (1.0f / 3.0f)};
    }
    const Sphere& sphere = geometry.spheres[prim - geometry.triangles.size()];
    std::vector<Vec3f> poles;
    for (int axis = 0; axis < 3; ++axis) {
        for (const float sign : {-1.0f, 1.0f}) {
            Vec3f pole = sphere.center;
            pole[axis] += sign * sphere.radius;
            poles.push_back(pole);
        }
    }
    return poles;
}

// Every node has a box and contains its children; every primitive is referenced by leaves whose boxes cover
// it: exactly one containing it without spatial splits, one or more, each with a part of it, with them (the
// points of points_of each lie in one of them).
void expect_valid_hierarchy(const BvhAccel& bvh, const Geometry& geometry, int max_leaf_size,
                            bool spatial_splits = false) {
    const HugePageVector<BvhNode>& nodes = bvh.nodes();
    std::vector<std::vector<std::uint32_t>> leaves_of(geometry.size());
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        const BvhNode& node = nodes[i];
        ASSERT_FALSE(node.bounds().empty()) << "node " << i;  // no reference was cut down to nothing
        if (node.is_leaf()) {
            ASSERT_LE(node.prim_count, max_leaf_size);
            for (std::uint32_t k = node.offset; k < node.offset + node.prim_count; ++k) {
                const std::uint32_t prim = bvh.prim_indices()[k];
                leaves_of[prim].push_back(static_cast<std::uint32_t>(i));
                if (!spatial_splits) {
                    ASSERT_TRUE(node.bounds().contains(primitive_bounds(geometry, prim))) << "leaf " << i;
                }
            }
        } else {
            ASSERT_LT(node.offset, nodes.size());
            ASSERT_GT(node.offset, i + 1);
            ASSERT_TRUE(node.bounds().contains(nodes[i + 1].bounds()));
            ASSERT_TRUE(node.bounds().contains(nodes[node.offset].bounds()));
        }
    }
    for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
        const std::vector<std::uint32_t>& leaves = leaves_of[prim];
        if (!spatial_splits) {
            ASSERT_EQ(leaves.size(), 1u) << "primitive " << prim;
        }
        for (const Vec3f& point : points_of(geometry, prim)) {
            ASSERT_TRUE(std::any_of(leaves.begin(), leaves.end(),
                                    [&](std::uint32_t leaf) { return nodes[leaf].bounds().contains(point); }))
                << "primitive " << prim;
        }
    }
    const AccelStats stats = bvh.stats();
    EXPECT_EQ(stats.count("nodes"), nodes.size());
    EXPECT_EQ(stats.count("leaves") * 2 - 1, nodes.size());  // a full binary tree
    EXPECT_EQ(stats.count("references"), bvh.prim_indices().size());
    if (spatial_splits) {
        EXPECT_GE(stats.count("references"), geometry.size());
        EXPECT_LE(stats.count("references"), geometry.size() * 3 / 2);  // the duplication budget
    } else {
        EXPECT_EQ(stats.count("references"), geometry.size());
    }
    EXPECT_LE(stats.value("max_depth"), BvhAccel::kMaxDepth);
    EXPECT_EQ(bvh.memory_bytes(),
              nodes.size() * sizeof(BvhNode) + stats.count("references") * sizeof(std::uint32_t));
}

TEST(Bvh, BothBuildersGiveValidHierarchies) {
    const std::vector<Triangle> triangles = knot_triangles(400);
    const std::vector<Sphere> spheres = {{{0, 0, 0}, 0.3f, 0}, {{1, 1, 0}, 0.1f, 0}};
    const Geometry geometry{triangles, spheres};
    for (BvhBuilder builder : {BvhBuilder::SweepSah, BvhBuilder::BinnedSah}) {
        for (int leaf : {1, 4, 16}) {
            BvhAccel bvh;
            bvh.build(geometry, with_builder(builder, leaf));
            expect_valid_hierarchy(bvh, geometry, leaf);
        }
    }
    for (int leaf : {1, 4, 16}) {
        BvhAccel bvh;
        bvh.build(geometry, with_spatial_splits(leaf));
        expect_valid_hierarchy(bvh, geometry, leaf, true);
    }
}

// The closest hits of brute force on random rays, rays through vertices and edges and axis-parallel rays,
// `count` of each (Moller-Trumbore, as `bvh` was built).
void expect_agrees_with_brute_force(const BvhAccel& bvh, const Geometry& geometry, std::size_t count) {
    const std::unique_ptr<Accel> brute = make_accel("brute");
    brute->build(geometry, {});
    for (const auto& set : {testing::random_rays(geometry.bounds(), count, 1),
                            testing::vertex_and_edge_rays(geometry.triangles, count, 2),
                            testing::axis_parallel_rays(geometry.bounds(), count, 3)}) {
        std::vector<Hit> expected(set.rays.size()), actual(set.rays.size());
        brute->intersect(set.rays, expected);
        bvh.intersect(set.rays, actual);
        const Agreement agreement = compare_hits(set.rays, expected, actual);
        EXPECT_EQ(agreement.mismatches, 0u) << set.name << ": " << agreement.summary();
    }
}

TEST(Bvh, SweepBuilderAgreesWithBruteForce) {
    const std::vector<Triangle> triangles = knot_triangles(300);
    const Geometry geometry{triangles, {}};
    BvhAccel bvh;
    bvh.build(geometry, with_builder(BvhBuilder::SweepSah));
    expect_agrees_with_brute_force(bvh, geometry, 5000);
}

// The root's split cost A(L) N(L) + A(R) N(R), from the built children (boxes shrunk back by the margin).
float root_split_cost(const BvhAccel& bvh) {
    const HugePageVector<BvhNode>& nodes = bvh.nodes();
    auto leaf_count = [&](std::uint32_t root) {
        std::size_t count = 0;
        std::vector<std::uint32_t> pending = {root};
        while (!pending.empty()) {
            const BvhNode& node = nodes[pending.back()];
            const std::uint32_t index = pending.back();
            pending.pop_back();
            if (node.is_leaf()) {
                count += node.prim_count;
            } else {
                pending.push_back(index + 1);
                pending.push_back(node.offset);
            }
        }
        return static_cast<float>(count);
    };
    return nodes[1].bounds().surface_area() * leaf_count(1) +
           nodes[nodes[0].offset].bounds().surface_area() * leaf_count(nodes[0].offset);
}

TEST(Bvh, FullSweepFindsARootSplitNoWorseThanBinning) {
    // Binning only considers bin boundaries, a subset of the sweep's candidates (Iehl's sweep,
    // "Intersections" 2011, is exact).
    for (int segments : {100, 250, 600}) {
        const std::vector<Triangle> triangles = knot_triangles(segments);
        BvhAccel sweep, binned;
        sweep.build({triangles, {}}, with_builder(BvhBuilder::SweepSah));
        binned.build({triangles, {}}, with_builder(BvhBuilder::BinnedSah));
        EXPECT_LE(root_split_cost(sweep), root_split_cost(binned) * (1.0f + 1e-5f)) << segments;
        EXPECT_GT(sweep.stats().value("sah_cost"), 0.0);
    }
}

// The two-pointer partition that pair_partition makes without branches: i up from the left, j down from the
// right, each stopping at an item on the wrong side, the two swapped.
std::size_t two_pointer_partition(std::vector<int>& items, const std::vector<char>& goes_left) {
    std::size_t i = 0, j = items.size();
    while (true) {
        while (i < j && goes_left[static_cast<std::size_t>(items[i])] != 0)
            ++i;
        while (i < j && goes_left[static_cast<std::size_t>(items[j - 1])] == 0)
            --j;
        if (i >= j) return i;
        std::swap(items[i++], items[--j]);
    }
}

TEST(PairPartition, LeavesTheTwoPointerPartitionsArrayWhateverTheBlocksAndThreads) {
    std::mt19937 rng(50);
    for (const std::size_t count : {0, 1, 2, 3, 17, 100, 1000, 40000}) {
        for (const double left_share : {0.0, 0.03, 0.5, 0.97, 1.0}) {
            std::vector<int> items(count);
            std::iota(items.begin(), items.end(), 0);
            std::shuffle(items.begin(), items.end(), rng);
            std::vector<char> goes_left(count);
            std::bernoulli_distribution left(left_share);
            for (char& side : goes_left)
                side = static_cast<char>(left(rng));
            std::vector<std::size_t> position_of(count);
            for (std::size_t i = 0; i < count; ++i)
                position_of[static_cast<std::size_t>(items[i])] = i;
            std::vector<int> expected = items;
            const std::size_t expected_middle = two_pointer_partition(expected, goes_left);
            for (const std::size_t block :
                 {std::max<std::size_t>(count, 1), std::size_t{1}, std::size_t{7}, std::size_t{4096}}) {
                for (const int threads : {1, 4}) {
                    std::vector<int> partitioned = items;
                    std::vector<std::uint32_t> scratch(count);
                    // Each item is classified once, by the block it lies in.
                    std::vector<int> calls(count, 0);
                    std::size_t middle = 0;
                    tbb::task_arena(threads).execute([&] {
                        middle = pair_partition(partitioned.data(), count, block, scratch.data(),
                                                [&](std::size_t block_index, int item) {
                                                    const auto i = static_cast<std::size_t>(item);
                                                    calls[i] +=
                                                        position_of[i] / block == block_index ? 1 : 100;
                                                    return goes_left[static_cast<std::size_t>(item)] != 0;
                                                });
                    });
                    EXPECT_EQ(middle, expected_middle) << count << " " << left_share << " " << block;
                    EXPECT_EQ(partitioned, expected) << count << " " << left_share << " " << block;
                    EXPECT_EQ(calls, std::vector<int>(count, 1))
                        << count << " " << left_share << " " << block;
                }
            }
        }
    }
}

TEST(Bvh, BuildIsDeterministicWhateverTheThreadCount) {
    // Large enough for the parallel binning, partition and subtrees to engage.
    const std::vector<Triangle> triangles = knot_triangles(6000);
    ASSERT_GT(triangles.size(), 2 * BinnedBuilder::kParallelBinning);
    for (const bool spatial_splits : {false, true}) {
        auto build_with = [&](int threads) {
            tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                      static_cast<std::size_t>(threads));
            BvhAccel bvh;
            bvh.build({triangles, {}}, with_builder(BvhBuilder::BinnedSah, 4, spatial_splits));
            return std::make_pair(bvh.nodes(), bvh.prim_indices());
        };
        const auto one = build_with(1);
        const auto two = build_with(2);
        const auto again = build_with(2);
        ASSERT_EQ(one.first.size(), two.first.size());
        EXPECT_EQ(std::memcmp(one.first.data(), two.first.data(), one.first.size() * sizeof(BvhNode)), 0);
        EXPECT_EQ(one.second, two.second);
        ASSERT_EQ(two.first.size(), again.first.size());
        EXPECT_EQ(std::memcmp(two.first.data(), again.first.data(), two.first.size() * sizeof(BvhNode)), 0);
        if (spatial_splits) {
            EXPECT_GT(one.second.size(), triangles.size());  // the spatial splits did happen
        }
    }
}

// build_bvh's whole leaves (the wide BVHs' binary build) are the full tree cut at its subtrees of at most
// that many references: the same nodes above them, in the same order, and each such subtree one leaf with
// its box and its primitives.
TEST(Bvh, WholeLeavesAreTheFullTreeCutAtTheirSize) {
    constexpr std::size_t kWholeLeafSize = 8;
    const std::vector<Triangle> triangles = knot_triangles(600);
    const Geometry geometry{triangles, {}};
    for (const BuildOptions& options :
         {with_builder(BvhBuilder::BinnedSah), with_builder(BvhBuilder::SweepSah), with_spatial_splits()}) {
        const BvhOptions& bvh_options = options.group<BvhOptions>();
        const BvhBuildResult full = build_bvh(geometry, bvh_options);
        const BvhBuildResult cut = build_bvh(geometry, bvh_options, kWholeLeafSize);
        // The primitives under each node of the full tree (children follow their parent).
        std::vector<std::vector<std::uint32_t>> prims_under(full.nodes.size());
        for (std::size_t i = full.nodes.size(); i-- > 0;) {
            const BvhNode& node = full.nodes[i];
            if (node.is_leaf()) {
                const auto first = full.prim_indices.begin() + node.offset;
                prims_under[i].assign(first, first + node.prim_count);
            } else {
                prims_under[i] = prims_under[i + 1];
                prims_under[i].insert(prims_under[i].end(), prims_under[node.offset].begin(),
                                      prims_under[node.offset].end());
            }
        }
        std::size_t next = 0;
        std::vector<std::uint32_t> pending = {0};
        while (!pending.empty()) {
            const std::uint32_t index = pending.back();
            pending.pop_back();
            const BvhNode& node = full.nodes[index];
            ASSERT_LT(next, cut.nodes.size());
            const BvhNode& cut_node = cut.nodes[next++];
            EXPECT_EQ(std::memcmp(&cut_node.lo, &node.lo, sizeof(Vec3f)), 0) << index;
            EXPECT_EQ(std::memcmp(&cut_node.hi, &node.hi, sizeof(Vec3f)), 0) << index;
            std::vector<std::uint32_t> expected = prims_under[index];
            ASSERT_EQ(cut_node.is_leaf(), node.is_leaf() || expected.size() <= kWholeLeafSize) << index;
            if (cut_node.is_leaf()) {
                const auto first = cut.prim_indices.begin() + cut_node.offset;
                std::vector<std::uint32_t> actual(first, first + cut_node.prim_count);
                std::sort(expected.begin(), expected.end());
                std::sort(actual.begin(), actual.end());
                EXPECT_EQ(actual, expected) << index;
                continue;
            }
            pending.push_back(node.offset);
            pending.push_back(index + 1);
        }
        EXPECT_EQ(next, cut.nodes.size());
        EXPECT_LT(cut.nodes.size(), full.nodes.size() / 2);
    }
}

TEST(Bvh, CoincidentPrimitivesStayBounded) {
    const std::vector<Triangle> triangles(5000, Triangle{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    for (const BuildOptions& options :
         {with_builder(BvhBuilder::SweepSah), with_builder(BvhBuilder::BinnedSah), with_spatial_splits()}) {
        BvhAccel bvh;
        bvh.build({triangles, {}}, options);
        expect_valid_hierarchy(bvh, {triangles, {}}, 4, options.group<BvhOptions>().spatial_splits);
        const Ray ray{{0.2f, 0.2f, 1.0f}, {0, 0, -1}, 0.0f, kInfinity};
        Hit hit;
        bvh.intersect({&ray, 1}, {&hit, 1});
        EXPECT_EQ(hit.prim, 0);  // the tie goes to the smallest index
    }
}

TEST(Bvh, SpatialSplitsIsASetKey) {
    BuildOptions options;
    EXPECT_FALSE(
        options.group<BvhOptions>().spatial_splits);  // off by default (docs/accel/bvh.md, "Spatial splits")
    set_build_option(options, "bvh.spatial_splits=true");
    EXPECT_TRUE(options.group<BvhOptions>().spatial_splits);
    set_build_option(options, "bvh.spatial_splits=false");
    EXPECT_FALSE(options.group<BvhOptions>().spatial_splits);
    EXPECT_THROW(set_build_option(options, "bvh.spatial_splits=yes"), std::invalid_argument);
}

TEST(Bvh, SpatialSplitsCutLongTriangles) {
    const std::vector<Triangle> triangles = testing::small_and_long_triangles(4000, 100);
    const Geometry geometry{triangles, {}};
    BvhAccel objects, spatial;
    objects.build(geometry, with_builder(BvhBuilder::BinnedSah));
    spatial.build(geometry, with_spatial_splits());
    expect_valid_hierarchy(spatial, geometry, 4, true);
    const AccelStats without = objects.stats(), with = spatial.stats();
    std::printf("small and long triangles: SAH %.1f without spatial splits, %.1f with, %zu references\n",
                without.value("sah_cost"), with.value("sah_cost"), with.count("references"));
    EXPECT_LT(with.value("sah_cost"), 0.7 * without.value("sah_cost"));
    EXPECT_GT(with.count("references"),
              triangles.size() + 400);  // the long triangles are cut several times each
    expect_agrees_with_brute_force(spatial, geometry, 4000);
}

// Only long thin triangles side by side along the diagonal of a cube: every node would cut every one of them.
TEST(Bvh, SpatialSplitsStopAtTheirBudget) {
    const std::vector<Triangle> triangles = testing::small_and_long_triangles(0, 3000);
    BvhAccel bvh;
    bvh.build({triangles, {}}, with_spatial_splits());
    expect_valid_hierarchy(bvh, {triangles, {}}, 4, true);
    EXPECT_EQ(bvh.stats().count("references"), triangles.size() * 3 / 2);  // used up, not exceeded
}

// Inputs that are hard on the cuts: degenerate triangles (points, segments), triangles lying in the planes of
// the spatial bins (a grid of axis-aligned squares, whose edges fall on the bins' planes) and the largest
// coordinates of the contract's domain.
TEST(Bvh, SpatialSplitsOnDegenerateInPlaneAndHugeTriangles) {
    std::mt19937 rng(13);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Triangle> hard;
    for (int i = 0; i < 16; ++i) {
        for (int j = 0; j < 16; ++j) {
            const auto x = static_cast<float>(i), y = static_cast<float>(j);
            hard.push_back({{x, y, 0}, {x + 1, y, 0}, {x + 1, y + 1, 0}});  // in the plane z = 0
            hard.push_back({{x, 0, y}, {x + 1, 0, y}, {x, 16, y + 1}});     // edges on bin planes
        }
    }
    for (int i = 0; i < 200; ++i) {
        const Vec3f a(16 * unit(rng), 16 * unit(rng), 16 * unit(rng));
        const Vec3f b(16 * unit(rng), 16 * unit(rng), 16 * unit(rng));
        hard.push_back({a, a, a});                 // a point
        hard.push_back({a, b, 0.5f * (a + b)});    // a segment
        hard.push_back({a, b, b + Vec3f(0.01f)});  // a sliver
    }
    std::vector<Triangle> huge;
    constexpr float limit = kCoordinateLimit;
    for (int i = 0; i < 300; ++i) {
        const Vec3f a = limit * Vec3f(2 * unit(rng) - 1, 2 * unit(rng) - 1, 2 * unit(rng) - 1);
        huge.push_back({a, -a, Vec3f(limit, -limit, limit * (2 * unit(rng) - 1))});
    }
    const std::vector<Sphere> spheres = {{{8, 8, 8}, 9.0f, 0}, {{1, 15, 3}, 0.0f, 0}, {{4, 4, 4}, 1e-3f, 0}};
    for (const Geometry geometry : {Geometry{hard, spheres}, Geometry{huge, {}}}) {
        for (const int leaf : {1, 4}) {
            BvhAccel bvh;
            bvh.build(geometry, with_spatial_splits(leaf));
            // The huge triangles' scene is built scaled into the ordinary range (Accel::built_geometry).
            expect_valid_hierarchy(bvh, bvh.built_geometry(), leaf, true);
            expect_agrees_with_brute_force(bvh, geometry, 3000);
        }
    }
}

TEST(Bvh, CountersSeeTheOrderedTraversal) {
    const std::vector<Triangle> triangles = knot_triangles(400);
    BvhAccel bvh;
    bvh.build({triangles, {}}, {});
    // A ray straight through the knot's hole touches few nodes; one through the tube more, yet far fewer
    // than the whole tree thanks to the front-to-back order and the early exit.
    const Ray through_tube{{1.5f, 0.0f, 5.0f}, {0, 0, -1}, 0.0f, kInfinity};
    Hit hit;
    TraversalCounters counters;
    bvh.intersect({&through_tube, 1}, {&hit, 1}, &counters);
    ASSERT_TRUE(hit.hit());
    EXPECT_LT(counters.nodes_visited, bvh.nodes().size() / 20);
    EXPECT_LT(counters.prims_tested, triangles.size() / 20);
}

}  // namespace
}  // namespace lancer
