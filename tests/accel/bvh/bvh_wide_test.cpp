// The 4- and 8-wide BVHs: structural invariants of the collapse, shallower than the binary tree, the SIMD
// box test equal to intersect_box (hit or miss and entry distance) on random and face-plane rays, and the
// triangle block kernels bit-identical to the scalar triangle tests. Agreement with brute force is the oracle
// test's (every registered structure).
#include "accel/bvh/bvh_wide.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <random>
#include <type_traits>
#include <vector>

#include "accel/brute.hpp"
#include "accel/build_util.hpp"
#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "lancer/huge_pages.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

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

// Every primitive in exactly one leaf slot whose box contains it, in that leaf's blocks with its vertices
// copied bit for bit (NaN for spheres and padding lanes, which come last); inner slots contain their node's
// children; empty slots are inverted, hold nothing and come after the used ones; every node but a tiny
// scene's root has at least two children.
template <int W>
void expect_valid_leaf(const WideBvhAccel<W>& bvh, const Geometry& geometry, std::uint32_t first_block,
                       std::uint32_t prim_count, const Box3f& box, std::vector<int>& seen) {
    using Block = typename WideBvhAccel<W>::Block;
    constexpr int kLanes = WideBvhAccel<W>::kBlockLanes;
    const std::uint32_t blocks = block_count(prim_count, kLanes);
    ASSERT_LE(first_block + blocks, bvh.blocks().size());
    for (std::uint32_t k = 0; k < blocks * kLanes; ++k) {
        const Block& block = bvh.blocks()[first_block + k / kLanes];
        const int lane = static_cast<int>(k % kLanes);
        const std::uint32_t prim = block.prim[lane];
        if (k >= prim_count) {
            ASSERT_EQ(prim, Block::kNoPrimitive);
            ASSERT_TRUE(std::isnan(block.vertex[0][0][lane]));
            continue;
        }
        ASSERT_LT(prim, geometry.size());
        ++seen[prim];
        ASSERT_TRUE(contains(box, primitive_bounds(geometry, prim)));
        if (prim < geometry.triangles.size()) {
            const Triangle copy = block.triangle(lane), &tri = geometry.triangles[prim];
            ASSERT_TRUE(copy.v0 == tri.v0 && copy.v1 == tri.v1 && copy.v2 == tri.v2) << "primitive " << prim;
        } else {
            ASSERT_TRUE(std::isnan(block.vertex[0][0][lane]));
        }
    }
}

template <int W>
void expect_valid_wide_hierarchy(const WideBvhAccel<W>& bvh, const Geometry& geometry, int max_leaf_size) {
    const HugePageVector<WideBvhNode<W>>& nodes = bvh.nodes();
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
                // A binary leaf, or a merged subtree of at most one block.
                ASSERT_LE(node.prim_count[slot],
                          static_cast<std::uint32_t>(std::max(max_leaf_size, WideBvhAccel<W>::kBlockLanes)));
                expect_valid_leaf(bvh, geometry, node.child[slot], node.prim_count[slot], box, seen);
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
    EXPECT_EQ(stats.count("references"), geometry.size());
    EXPECT_EQ(stats.count("nodes"), nodes.size() + stats.count("leaves"));
    EXPECT_EQ(bvh.memory_bytes(), nodes.size() * sizeof(WideBvhNode<W>) +
                                      bvh.blocks().size() * sizeof(typename WideBvhAccel<W>::Block));
}

template <int W>
void check_structure(const Geometry& geometry) {
    for (int leaf : {1, 4, 16}) {
        BuildOptions options;
        options.group<BvhOptions>().max_leaf_size = leaf;
        WideBvhAccel<W> wide;
        wide.build(geometry, options);
        expect_valid_wide_hierarchy(wide, geometry, leaf);
        // Binary leaves of one primitive: the subtrees of up to one block were merged into leaves.
        if (leaf == 1) {
            EXPECT_EQ(wide.stats().count("max_refs_per_leaf"),
                      static_cast<std::size_t>(WideBvhAccel<W>::kBlockLanes));
        }
    }
}

// The walks visit a node's hit children nearest first, equal entries in slot order: the nearest, then the
// pushed ones as the stack pops them (push_farther_children, whose one- and two-child cases skip the sort).
// Every mask of 8 children, entries drawn from three values so that ties are common.
TEST(WideBvh, ChildrenAreVisitedByEntryThenSlot) {
    std::mt19937 rng(8);
    std::uniform_int_distribution<int> value(0, 2);
    for (unsigned mask = 1; mask < 256; ++mask) {
        for (int draw = 0; draw < 20; ++draw) {
            float entry[8];
            for (float& e : entry)
                e = static_cast<float>(value(rng));
            std::vector<int> expected;
            for (int slot = 0; slot < 8; ++slot) {
                if ((mask >> slot) & 1u) expected.push_back(slot);
            }
            std::stable_sort(expected.begin(), expected.end(),
                             [&](int a, int b) { return entry[a] < entry[b]; });
            std::vector<int> pushed;
            const int nearest =
                push_farther_children<8>(mask, entry, [&](int slot) { pushed.push_back(slot); });
            std::vector<int> visited{nearest};
            visited.insert(visited.end(), pushed.rbegin(), pushed.rend());
            ASSERT_EQ(visited, expected) << "mask " << mask;
        }
    }
}

TEST(WideBvh, CollapseGivesValidHierarchies) {
    const std::vector<Triangle> triangles = knot_triangles(400);
    const std::vector<Sphere> spheres = {{{0, 0, 0}, 0.3f, 0}, {{1, 1, 0}, 0.1f, 0}};
    const Geometry geometry{triangles, spheres};
    check_structure<4>(geometry);
    check_structure<8>(geometry);
}

// With spatial splits a primitive may sit in several leaves, but in none twice: the subtrees the collapse
// merges into one block are too small for spatial splits (docs/accel/bvh.md, "Spatial splits").
template <int W>
void expect_leaves_hold_each_primitive_once(const Geometry& geometry, int max_leaf_size) {
    BuildOptions options;
    options.group<BvhOptions>().max_leaf_size = max_leaf_size;
    options.group<BvhOptions>().spatial_splits = true;
    WideBvhAccel<W> bvh;
    bvh.build(geometry, options);
    std::vector<int> leaves_of(geometry.size(), 0);
    std::size_t references = 0;
    for (const WideBvhNode<W>& node : bvh.nodes()) {
        for (int slot = 0; slot < W; ++slot) {
            if (node.is_empty(slot) || node.prim_count[slot] == 0) continue;
            std::vector<std::uint32_t> prims;
            for (std::uint32_t k = 0; k < node.prim_count[slot]; ++k) {
                const auto& block = bvh.blocks()[node.child[slot] + k / WideBvhAccel<W>::kBlockLanes];
                prims.push_back(block.prim[k % WideBvhAccel<W>::kBlockLanes]);
            }
            std::sort(prims.begin(), prims.end());
            ASSERT_EQ(std::adjacent_find(prims.begin(), prims.end()), prims.end());
            for (const std::uint32_t prim : prims)
                ++leaves_of[prim];
            references += prims.size();
        }
    }
    EXPECT_EQ(std::count(leaves_of.begin(), leaves_of.end(), 0), 0);
    EXPECT_EQ(bvh.stats().count("references"), references);
    EXPECT_GT(references, geometry.size());  // the spatial splits did cut
}

TEST(WideBvh, LeavesHoldEachPrimitiveOnce) {
    const std::vector<Triangle> triangles = testing::small_and_long_triangles(4000, 100);
    for (const int leaf : {1, 4, 16}) {
        expect_leaves_hold_each_primitive_once<4>({triangles, {}}, leaf);
        expect_leaves_hold_each_primitive_once<8>({triangles, {}}, leaf);
    }
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
    EXPECT_EQ(empty.stats().count("leaves"), 0u);
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
    // The binary leaves, fewer where subtrees of one block (4 or 8 primitives) were merged; collapsed inner
    // levels.
    EXPECT_LT(s4.count("leaves"), b.count("leaves"));
    EXPECT_LT(s8.count("leaves"), s4.count("leaves"));
    EXPECT_LT(s4.count("nodes"), b.count("nodes"));
    EXPECT_LT(s8.count("nodes"), s4.count("nodes"));
    EXPECT_LT(s4.value("max_depth"), b.value("max_depth"));
    EXPECT_LT(s8.value("max_depth"), s4.value("max_depth"));
    EXPECT_LT(s4.value("mean_depth"), b.value("mean_depth"));
    EXPECT_LT(s8.value("mean_depth"), s4.value("mean_depth"));
    EXPECT_GT(s8.value("sah_cost"), 0.0);
}

// Binary leaves larger than a block (max_leaf_size 16) take several blocks, in a scene mixing spheres among
// the triangles: closest hits and occlusion agree with brute force for both widths and both triangle tests.
template <int W>
void check_multi_block_leaves(TriangleTest test) {
    // Twelve copies of one triangle: no split separates them, so they make one leaf of several blocks.
    std::vector<Triangle> triangles = knot_triangles(300);
    triangles.insert(triangles.end(), 12, triangles[7]);
    const std::vector<Sphere> spheres = {
        {{0, 0, 0}, 0.3f, 0}, {{1, 1, 0}, 0.1f, 0}, {{-1, 0, 0.5f}, 0.2f, 0}};
    const Geometry geometry{triangles, spheres};
    BuildOptions options = build_options(test);
    options.group<BvhOptions>().max_leaf_size = 16;
    WideBvhAccel<W> wide;
    wide.build(geometry, options);
    ASSERT_GT(wide.stats().count("max_refs_per_leaf"),
              static_cast<std::size_t>(WideBvhAccel<W>::kBlockLanes));
    BruteAccel brute;
    brute.build(geometry, options);
    for (const testing::RaySet& set : {testing::random_rays(geometry.bounds(), 4000, 5),
                                       testing::vertex_and_edge_rays(triangles, 4000, 6)}) {
        std::vector<Hit> expected(set.rays.size()), actual(set.rays.size());
        std::vector<std::uint8_t> occluded(set.rays.size());
        brute.intersect(set.rays, expected);
        wide.intersect(set.rays, actual);
        wide.occluded(set.rays, occluded);
        const Agreement hits = compare_hits(set.rays, expected, actual);
        EXPECT_EQ(hits.mismatches, 0u) << set.name << ": " << hits.first_mismatch;
        EXPECT_GT(hits.hits, set.rays.size() / 10) << set.name;
        const Agreement occlusion = compare_occlusion(set.rays, expected, occluded);
        EXPECT_EQ(occlusion.mismatches, 0u) << set.name << ": " << occlusion.first_mismatch;
    }
}

TEST(WideBvh, LeavesOfSeveralBlocksAgreeWithBruteForce) {
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        check_multi_block_leaves<4>(test);
        check_multi_block_leaves<8>(test);
    }
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

// Triangles that exercise the kernels' edge cases: random, on an integer grid (rays through their vertices
// and edges give exactly zero watertight edge functions), sharing an edge or copying the previous triangle
// (ties, resolved by index), with a repeated vertex, collinear, tiny, huge (overflowing products), or with a
// NaN.
std::vector<Triangle> adversarial_triangles(std::mt19937& rng, int count) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_int_distribution<int> grid(-2, 2), kind(0, 9);
    auto point = [&] { return Vec3f(unit(rng), unit(rng), unit(rng)); };
    auto grid_point = [&] {
        return Vec3f(static_cast<float>(grid(rng)), static_cast<float>(grid(rng)),
                     static_cast<float>(grid(rng)));
    };
    std::vector<Triangle> triangles = {{point(), point(), point()}};
    while (static_cast<int>(triangles.size()) < count) {
        const Triangle previous = triangles.back();
        Triangle tri{point(), point(), point()};
        switch (kind(rng)) {
            case 0:
                tri = {grid_point(), grid_point(), grid_point()};
                break;
            case 1:
                tri = {grid_point(), grid_point(), grid_point()};
                break;
            case 2:
                tri = {previous.v1, previous.v0, point()};
                break;
            case 3:
                tri = previous;
                break;
            case 4:
                tri.v1 = tri.v0;
                break;
            case 5:
                tri.v2 = tri.v0 + 2.0f * (tri.v1 - tri.v0);
                break;
            case 6:
                tri = {tri.v0, tri.v0 + 1e-7f * point(), tri.v0 + 1e-7f * point()};
                break;
            case 7:
                tri = {1e30f * point(), 1e30f * point(), 1e30f * point()};
                break;
            case 8:
                tri.v2.y = std::numeric_limits<float>::quiet_NaN();
                break;
            default:
                break;
        }
        triangles.push_back(tri);
    }
    return triangles;
}

// A ray aimed at a triangle's vertex, edge midpoint or interior, or axis-parallel from a grid point, or
// random; sometimes with a cut interval.
Ray adversarial_ray(std::mt19937& rng, const Triangle& target) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), positive(0.0f, 1.0f);
    std::uniform_int_distribution<int> grid(-3, 3), kind(0, 5), axis(0, 2);
    auto grid_point = [&] {
        return Vec3f(static_cast<float>(grid(rng)), static_cast<float>(grid(rng)),
                     static_cast<float>(grid(rng)));
    };
    Vec3f origin = 3.0f * Vec3f(unit(rng), unit(rng), unit(rng)), aim;
    switch (kind(rng)) {
        case 0:
            aim = target.v0;
            break;
        case 1:
            aim = 0.5f * (target.v0 + target.v1);
            break;
        case 2: {
            const float a = positive(rng), b = positive(rng) * (1.0f - a);
            aim = target.v0 + a * (target.v1 - target.v0) + b * (target.v2 - target.v0);
            break;
        }
        case 3: {
            origin = grid_point();
            aim = origin;
            aim[axis(rng)] += unit(rng) < 0.0f ? -1.0f : 1.0f;
            break;
        }
        default:
            aim = Vec3f(unit(rng), unit(rng), unit(rng));
            break;
    }
    Ray ray{origin, aim - origin, 0.0f, kInfinity};
    if (kind(rng) == 0) ray.tnear = positive(rng), ray.tfar = ray.tnear + positive(rng);
    return ray;
}

bool same_bits(float a, float b) {
    return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b);
}

struct KernelCheckCounts {
    std::size_t lane_hits = 0, scalar_lanes = 0, closest_hits = 0, occluded = 0;
};

// For random blocks of K primitives of a mixed scene (spheres among the triangles, padding at the end):
// every lane the block kernel decides agrees with the scalar test (hit or miss, and t, u, v bit for bit),
// intersect_block gives the scalar loop's closest hit (bit for bit, ties to the smaller index) from a random
// starting hit, and occludes_block the scalar loop's answer.
template <class TriangleTestT, int K>
void check_block_kernel(std::uint32_t seed, KernelCheckCounts& counts) {
    std::mt19937 rng(seed);
    const std::vector<Triangle> triangles = adversarial_triangles(rng, 400);
    const std::vector<Sphere> spheres = {{{0, 0, 0}, 0.5f, 0}, {{1, 0, 0}, 0.25f, 0}};
    const Geometry geometry{triangles, spheres};
    std::uniform_int_distribution<std::uint32_t> any_prim(0, static_cast<std::uint32_t>(geometry.size() - 1));
    std::uniform_int_distribution<std::uint32_t> any_triangle(
        0, static_cast<std::uint32_t>(triangles.size() - 1));
    std::uniform_int_distribution<int> lanes(1, K), choice(0, 9);
    for (int trial = 0; trial < 20000; ++trial) {
        // Mostly neighbours in the triangle list, so that shared edges and copies land in one block.
        std::vector<std::uint32_t> prims;
        const std::uint32_t start = any_triangle(rng);
        const int used = lanes(rng);
        for (int lane = 0; lane < used; ++lane) {
            const std::uint32_t neighbour = std::min<std::uint32_t>(
                start + static_cast<std::uint32_t>(lane), static_cast<std::uint32_t>(triangles.size() - 1));
            const std::uint32_t prim = choice(rng) == 0 ? any_prim(rng) : neighbour;
            if (std::find(prims.begin(), prims.end(), prim) == prims.end()) prims.push_back(prim);
        }
        std::shuffle(prims.begin(), prims.end(), rng);
        std::vector<TriangleBlock<K>> blocks;
        append_leaf_blocks(geometry, std::span<const std::uint32_t>(prims), blocks);
        ASSERT_EQ(blocks.size(), 1u);
        const TriangleBlock<K>& block = blocks[0];

        const Ray ray = adversarial_ray(rng, triangles[start]);
        if (!is_valid(ray)) continue;
        const PreparedRay<TriangleTestT> prepared(ray);
        const BlockRay<TriangleTestT, K> block_ray(prepared, geometry);

        BlockHits<K> hits;
        block_ray.kernel.test(block, ray.tnear, ray.tfar, hits);
        counts.scalar_lanes += static_cast<std::size_t>(std::popcount(hits.scalar_lanes));
        for (int lane = 0; lane < K; ++lane) {
            const bool kernel_hit = (hits.hit_lanes >> lane) & 1u;
            const bool is_triangle = lane < static_cast<int>(prims.size()) && prims[lane] < triangles.size();
            if (!is_triangle) {
                ASSERT_FALSE(kernel_hit) << "trial " << trial << ": a padding or sphere lane hit";
                continue;
            }
            if ((hits.scalar_lanes >> lane) & 1u) continue;
            TriangleHit expected;
            const bool scalar_hit = TriangleTestT::intersect(prepared.triangle_data, triangles[prims[lane]],
                                                             ray.tnear, ray.tfar, expected);
            ASSERT_EQ(kernel_hit, scalar_hit) << "trial " << trial << " lane " << lane;
            if (!kernel_hit) continue;
            ++counts.lane_hits;
            ASSERT_TRUE(same_bits(hits.t[lane], expected.t) && same_bits(hits.u[lane], expected.u) &&
                        same_bits(hits.v[lane], expected.v))
                << "trial " << trial << " lane " << lane;
        }

        Hit start_hit;
        if (choice(rng) < 3)
            start_hit = {4.0f * std::abs(static_cast<float>(choice(rng))) / 9.0f,
                         static_cast<std::int32_t>(any_prim(rng)), 0.25f, 0.5f};
        Hit expected = start_hit, actual = start_hit;
        for (const std::uint32_t prim : prims)
            intersect_primitive(geometry, prim, prepared, expected);
        intersect_block(geometry, block, block_ray, actual);
        ASSERT_EQ(actual.prim, expected.prim) << "trial " << trial;
        ASSERT_TRUE(same_bits(actual.t, expected.t) && same_bits(actual.u, expected.u) &&
                    same_bits(actual.v, expected.v))
            << "trial " << trial;
        counts.closest_hits += expected.prim != start_hit.prim;

        bool expected_occluded = false;
        for (const std::uint32_t prim : prims)
            expected_occluded = expected_occluded || occludes(geometry, prim, prepared);
        ASSERT_EQ(occludes_block(geometry, block, block_ray), expected_occluded) << "trial " << trial;
        counts.occluded += expected_occluded;
    }
}

template <class TriangleTestT>
void check_block_kernels(std::uint32_t seed) {
    KernelCheckCounts counts;
    check_block_kernel<TriangleTestT, 4>(seed, counts);
    check_block_kernel<TriangleTestT, 8>(seed + 1, counts);
    // Not a degenerate sample: many lanes hit, many closest hits change, and both tests hand many lanes to
    // their double fallback: the watertight test its zero and denormal edge functions (grid triangles,
    // repeated vertices; 34,989 with these seeds), Moller-Trumbore its grazing lanes and those within its
    // error bound of an edge (9,054; 47 grazing ones before fuzz finding 23).
    EXPECT_GT(counts.lane_hits, 6000u);
    EXPECT_GT(counts.closest_hits, 5000u);
    EXPECT_GT(counts.occluded, 5000u);
    EXPECT_GT(counts.scalar_lanes, 1000u);
}

TEST(TriangleBlock, MollerTrumboreBlockEqualsScalarTest) {
    check_block_kernels<MollerTrumbore>(11);
}

TEST(TriangleBlock, WatertightBlockEqualsScalarTest) {
    check_block_kernels<Watertight>(21);
}

// A lane whose ray lies on one edge's line (that edge function exactly 0, so uncertain) while the other two
// edge functions are certain and of opposite signs is a miss the vector kernel decides itself, as the
// scalar kernel's first test would, instead of handing it to the scalar kernel (docs/accel/bvh_wide.md,
// "Uncertain lanes that are misses"). A lane on an edge's line between two certain edge functions of one
// sign still goes to the scalar kernel, which decides the exact sign.
TEST(TriangleBlock, WatertightKernelKeepsCertainMisses) {
    const std::vector<Triangle> triangles = {
        {{1.0f, 0.0f, 0.0f}, {2.0f, 0.0f, 0.0f}, {1.5f, 1.0f, 0.0f}},    // the ray on v0 v1's line, beside it
        {{-1.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}}};  // the ray on the edge v0 v1 itself
    const Geometry geometry{triangles, {}};
    const Ray ray{{0.0f, 0.0f, -10.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, kInfinity};
    const PreparedRay<Watertight> prepared(ray);
    std::vector<TriangleBlock<8>> blocks;
    const std::uint32_t prims[] = {0, 1};
    append_leaf_blocks(geometry, std::span<const std::uint32_t>(prims), blocks);
    ASSERT_EQ(blocks.size(), 1u);
    const BlockRay<Watertight, 8> block_ray(prepared, geometry);
    BlockHits<8> hits;
    block_ray.kernel.test(blocks[0], ray.tnear, ray.tfar, hits);
    EXPECT_EQ(hits.scalar_lanes, 0b10u);  // the first lane decided here, the second by the scalar kernel
    EXPECT_EQ(hits.hit_lanes & 1u, 0u);
    TriangleHit scalar;
    EXPECT_FALSE(Watertight::intersect(prepared.triangle_data, triangles[0], ray.tnear, ray.tfar, scalar));
}

// The arrays a structure keeps, and the scene's flattened triangles, start on a huge page once they are
// large enough for HugePageAllocator to align them (include/lancer/huge_pages.hpp): each is checked to be
// that large first, so that a plain std::vector, whose heap storage never starts on one, fails.
TEST(WideBvh, LargeArraysStartOnHugePages) {
    Scene scene;
    scene.meshes.push_back(make_icosphere(7));  // 327,680 triangles
    const SceneGeometry geometry(scene);
    Bvh8Accel bvh8;
    bvh8.build(geometry.view(), BuildOptions{});
    const auto expect_on_a_huge_page = [](const auto& array, const char* name) {
        using Element = std::remove_cvref_t<decltype(array[0])>;
        ASSERT_TRUE(HugePageAllocator<Element>::in_huge_pages(array.size())) << name;
        EXPECT_EQ(reinterpret_cast<std::uintptr_t>(array.data()) % kHugePageBytes, 0u) << name;
    };
    expect_on_a_huge_page(geometry.view().triangles, "triangles");
    expect_on_a_huge_page(bvh8.nodes(), "wide nodes");
    expect_on_a_huge_page(bvh8.blocks(), "triangle blocks");
}

}  // namespace
}  // namespace lancer
