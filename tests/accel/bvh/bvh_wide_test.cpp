// The 4- and 8-wide BVHs: structural invariants of the collapse, shallower than the binary tree, the SIMD
// box test equal to intersect_box (hit or miss and entry distance) on random and face-plane rays. The
// triangle block kernels are triangle_block_test.cpp's; agreement with brute force is the oracle test's
// (every registered structure).
#include "accel/bvh/bvh_wide.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <random>
#include <vector>

#include "accel/brute.hpp"
#include "accel/build_util.hpp"
#include "accel/bvh/small_subtree.hpp"
#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "lancer/huge_pages.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::knot_triangles;

bool is_inverted(const Box3f& box) {
    return box.lo.x == kInfinity && box.lo.y == kInfinity && box.lo.z == kInfinity &&
           box.hi.x == -kInfinity && box.hi.y == -kInfinity && box.hi.z == -kInfinity;
}

// A leaf's header (has_leaf_boxes): lane b holds a box, within the leaf's, around every primitive of the
// leaf's block b; the lanes past its blocks are inverted and it holds no primitive.
void expect_valid_leaf_boxes(const Bvh8Accel& bvh, const Geometry& geometry, std::uint32_t child,
                             std::uint32_t prim_count, const Box3f& leaf_box) {
    const LeafSpan span = leaf_span<8>(child, prim_count);
    ASSERT_EQ(span.first, leaf_start(child) + 1);
    const Bvh8Accel::Block& header = bvh.blocks()[leaf_start(child)];
    for (int lane = 0; lane < 8; ++lane) {
        ASSERT_EQ(header.prim[lane], Bvh8Accel::Block::kNoPrimitive);
        const Box3f box{{header.vertex[0][0][lane], header.vertex[0][1][lane], header.vertex[0][2][lane]},
                        {header.vertex[1][0][lane], header.vertex[1][1][lane], header.vertex[1][2][lane]}};
        const std::uint32_t b = span.first + static_cast<std::uint32_t>(lane);
        if (b >= span.end) {
            ASSERT_TRUE(is_inverted(box)) << "header lane " << lane;
            continue;
        }
        ASSERT_TRUE(leaf_box.contains(box)) << "header lane " << lane;
        for (const std::uint32_t prim : bvh.blocks()[b].prim) {
            if (prim == Bvh8Accel::Block::kNoPrimitive) continue;
            ASSERT_TRUE(box.contains(primitive_bounds(geometry, prim))) << "primitive " << prim;
        }
    }
}

// Every primitive in exactly one leaf slot whose box contains it, in that leaf's blocks with its vertices
// copied bit for bit (NaN for spheres and padding lanes, which come last), after its header where it has one;
// inner slots contain their node's children; empty slots are inverted, hold nothing and come after the used
// ones; every node but a tiny scene's root has at least two children.
template <int W>
void expect_valid_leaf(const WideBvhAccel<W>& bvh, const Geometry& geometry, std::uint32_t child,
                       std::uint32_t prim_count, const Box3f& box, std::vector<int>& seen) {
    using Block = typename WideBvhAccel<W>::Block;
    constexpr int kLanes = WideBvhAccel<W>::kBlockLanes;
    const std::uint32_t blocks = block_count(prim_count, kLanes);
    const std::uint32_t first_block = leaf_span<W>(child, prim_count).first;
    ASSERT_LE(first_block + blocks, bvh.blocks().size());
    if constexpr (W == 8) {
        if (has_leaf_boxes(child)) {
            ASSERT_GT(blocks, 1u) << "a header in front of one block";
            expect_valid_leaf_boxes(bvh, geometry, child, prim_count, box);
        }
    } else {
        ASSERT_FALSE(has_leaf_boxes(child)) << "bvh4's leaves have no header";
    }
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
        ASSERT_TRUE(box.contains(primitive_bounds(geometry, prim)));
        if (prim < geometry.triangles.size()) {
            const Triangle copy = block.triangle(lane), &tri = geometry.triangles[prim];
            ASSERT_TRUE(copy.v0 == tri.v0 && copy.v1 == tri.v1 && copy.v2 == tri.v2) << "primitive " << prim;
        } else {
            ASSERT_TRUE(std::isnan(block.vertex[0][0][lane]));
        }
    }
}

// `max_leaf_size` and `wide_leaf_size`: the options the tree was built with (BvhOptions).
template <int W>
void expect_valid_wide_hierarchy(const WideBvhAccel<W>& bvh, const Geometry& geometry, int max_leaf_size,
                                 int wide_leaf_size) {
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
                // A binary leaf, or a merged subtree of at most wide_leaf_size primitives (or one block).
                ASSERT_LE(node.prim_count[slot],
                          static_cast<std::uint32_t>(
                              std::max({max_leaf_size, wide_leaf_size, WideBvhAccel<W>::kBlockLanes})));
                expect_valid_leaf(bvh, geometry, node.child[slot], node.prim_count[slot], box, seen);
            } else {
                ASSERT_GT(node.child[slot], i);
                ASSERT_LT(node.child[slot], nodes.size());
                const WideBvhNode<W>& child = nodes[node.child[slot]];
                for (int child_slot = 0; child_slot < W; ++child_slot) {
                    if (child.is_empty(child_slot)) continue;
                    ASSERT_TRUE(box.contains(child.child_bounds(child_slot)));
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
    constexpr int kDefaultWideLeafSize = BvhOptions{}.wide_leaf_size;
    for (int leaf : {1, 4, 16}) {
        for (int wide_leaf : {1, W, kDefaultWideLeafSize}) {
            BuildOptions options;
            options.group<BvhOptions>().max_leaf_size = leaf;
            options.group<BvhOptions>().wide_leaf_size = wide_leaf;
            WideBvhAccel<W> wide;
            for (const LeafBoxes boxes : {LeafBoxes::Auto, LeafBoxes::Off, LeafBoxes::On}) {
                options.group<BvhOptions>().leaf_boxes = boxes;
                wide.build(geometry, options);
                expect_valid_wide_hierarchy(wide, geometry, leaf, wide_leaf);
                // Headers where asked for and where some leaf holds more than one block: in bvh8 only, and
                // not by auto, which leaves them to bvh8_packet's tree (its walk steps over them).
                const auto arrays = wide.stats().memory_by_array;
                const bool headers = std::any_of(arrays.begin(), arrays.end(), [](const auto& array) {
                    return array.first == "leaf boxes" && array.second > 0;
                });
                EXPECT_EQ(headers, W == 8 && boxes == LeafBoxes::On && wide_leaf > W)
                    << "max_leaf_size " << leaf << ", wide_leaf_size " << wide_leaf;
            }
            if (leaf != 1) continue;
            // Binary leaves of one primitive: the subtrees of up to one block (wide_leaf_size 1 and W), or
            // of more than one block (the default), were merged into leaves.
            const std::size_t largest = wide.stats().count("max_refs_per_leaf");
            if (wide_leaf <= W)
                EXPECT_EQ(largest, static_cast<std::size_t>(W)) << "wide_leaf_size " << wide_leaf;
            else
                EXPECT_GT(largest, static_cast<std::size_t>(W)) << "wide_leaf_size " << wide_leaf;
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
            // A write left uncounted must be one the stack drops: the walk's next push overwrites it.
            std::vector<int> pushed;
            int uncounted = 0;
            const int nearest = push_farther_children<8>(mask, entry, [&](int slot, bool counted) {
                if (counted) {
                    pushed.push_back(slot);
                } else {
                    ++uncounted;
                }
            });
            std::vector<int> visited{nearest};
            visited.insert(visited.end(), pushed.rbegin(), pushed.rend());
            ASSERT_EQ(visited, expected) << "mask " << mask;
            ASSERT_LE(uncounted, std::popcount(mask) == 1 ? 1 : 0) << "mask " << mask;
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
            const std::uint32_t first_block = leaf_span<W>(node.child[slot], node.prim_count[slot]).first;
            for (std::uint32_t k = 0; k < node.prim_count[slot]; ++k) {
                const auto& block = bvh.blocks()[first_block + k / WideBvhAccel<W>::kBlockLanes];
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

// A wide leaf size set in code, past the registry's range, builds the tree of the largest allowed one: no
// leaf beyond kExactSplitBelow primitives (bvh_wide.cpp says why).
TEST(WideBvh, WideLeafSizeIsClampedToTheExactSplitBound) {
    const std::vector<Triangle> triangles = knot_triangles(2000);
    const Geometry geometry{triangles, {}};
    const auto build = [&](int wide_leaf_size) {
        BuildOptions options;
        options.group<BvhOptions>().max_leaf_size = 1;
        options.group<BvhOptions>().wide_leaf_size = wide_leaf_size;
        Bvh8Accel bvh8;
        bvh8.build(geometry, options);
        return bvh8.stats();
    };
    const AccelStats too_large = build(1000), largest = build(static_cast<int>(kExactSplitBelow));
    EXPECT_LE(too_large.count("max_refs_per_leaf"), kExactSplitBelow);
    EXPECT_EQ(too_large.count("leaves"), largest.count("leaves"));
    EXPECT_EQ(too_large.count("nodes"), largest.count("nodes"));
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
    BuildOptions one_block;
    one_block.group<BvhOptions>().wide_leaf_size = 1;
    Bvh4Accel bvh4_one_block;
    bvh4_one_block.build(geometry, one_block);
    Bvh8Accel bvh8_one_block;
    bvh8_one_block.build(geometry, one_block);
    const AccelStats b = binary.stats(), s4 = bvh4.stats(), s8 = bvh8.stats();
    const AccelStats s4_one = bvh4_one_block.stats(), s8_one = bvh8_one_block.stats();
    // The binary leaves, fewer where subtrees of one block (4 or 8 primitives) were merged, fewer again where
    // subtrees of up to bvh.wide_leaf_size were, the same ones in both widths; collapsed inner levels.
    EXPECT_LT(s4_one.count("leaves"), b.count("leaves"));
    EXPECT_LT(s8_one.count("leaves"), s4_one.count("leaves"));
    EXPECT_LT(s8.count("leaves"), s8_one.count("leaves"));
    EXPECT_EQ(s4.count("leaves"), s8.count("leaves"));
    EXPECT_LT(s8.value("mean_depth"), s8_one.value("mean_depth"));
    EXPECT_LT(s4.value("mean_depth"), s4_one.value("mean_depth"));
    for (const char* figure : {"nodes", "max_depth", "mean_depth"}) {
        EXPECT_LT(s4.value(figure), b.value(figure)) << figure;
        EXPECT_LT(s8.value(figure), s4.value(figure)) << figure;
    }
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

// The arrays a structure keeps, and the scene's flattened triangles, start on a huge page once they are
// large enough for HugePageAllocator to align them (include/lancer/huge_pages.hpp): each is checked to be
// that large first, so that a plain std::vector, whose heap storage never starts on one, fails.
TEST(WideBvh, LargeArraysStartOnHugePages) {
    Scene scene;
    scene.meshes.push_back(make_icosphere(7));  // 327,680 triangles
    const SceneGeometry geometry(scene);
    // Leaves of one block, so that the nodes too outgrow a huge page (merged leaves take a quarter of them).
    BuildOptions options;
    options.group<BvhOptions>().wide_leaf_size = 1;
    Bvh8Accel bvh8;
    bvh8.build(geometry.view(), options);
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
