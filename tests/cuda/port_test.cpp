// The GPU traversals run on the CPU (src/cuda/*.hpp compiled by g++) over the flattened arrays, against the
// CPU structures on the same rays: the Plücker walk against `plucker`, the Aila-Laine while-while and
// speculative while-while traversals against `bvh`, bit for bit (t, primitive, u, v): the arithmetic is
// the same, so any difference is a porting error. This proves the ports' logic; the launch, the transfers
// and the device compiler are left to gpu_test.cpp, on a machine with a GPU.
#include <gtest/gtest.h>

#include <cstring>

#include "accel/bvh/bvh.hpp"
#include "accel/plucker/plucker.hpp"
#include "core/intersect.hpp"
#include "cuda/bvh_traversal.hpp"
#include "cuda/flatten.hpp"
#include "cuda/plucker_walk.hpp"
#include "lancer/camera.hpp"
#include "port_scenes.hpp"

namespace lancer {
namespace {

using testing::BunnyCanonicalView;
using testing::count_differences;
using testing::count_hits;
using testing::make_triangle_scenes;
using testing::occlusion_each;
using testing::ray_sets_for;
using testing::TestScene;
using testing::trace_each;

// The walk compiled for Layout against the CPU walk of the same octree.
template <class TriangleTestT, class Layout>
void expect_walk_agrees(const PluckerAccel& octree, const plucker::PluckerTables& tables,
                        const testing::RaySet& set, const std::string& where) {
    const plucker::PluckerView view = gpu::plucker_view(octree.layout());
    ASSERT_EQ(view.balanced, Layout::kBalanced);
    ASSERT_EQ(view.stored_boxes, Layout::kStoredBoxes);
    std::vector<Hit> expected(set.rays.size());
    octree.intersect(set.rays, expected);
    const auto walk = trace_each(set.rays, octree.bounds(), [&](const Ray& ray) {
        return gpu::trace_plucker<TriangleTestT, Layout>(view, tables, ray);
    });
    std::string first;
    const std::string layout_name = std::string(Layout::kBalanced ? "2:1" : "unconstrained") + ", " +
                                    (Layout::kStoredBoxes ? "stored" : "computed") + " boxes";
    EXPECT_EQ(count_differences(expected, walk, first), 0u)
        << where << "plucker walk (" << layout_name << "), " << first;
    std::vector<std::uint8_t> expected_occlusion(set.rays.size());
    octree.occluded(set.rays, expected_occlusion);
    const auto occlusion = occlusion_each(set.rays, octree.bounds(), [&](const Ray& ray) {
        return gpu::trace_plucker<TriangleTestT, Layout, true>(view, tables, ray);
    });
    EXPECT_EQ(count_differences(expected_occlusion, occlusion), 0u)
        << where << "plucker walk's occlusion (" << layout_name << ")";
}

// The four GPU traversals of one triangle test on the CPU, against the two CPU structures; the BVH with
// spatial splits where `spatial_splits` (its leaves then share primitives, which the flattened BVH copies).
template <class TriangleTestT>
void expect_ports_agree(const Geometry& geometry, TriangleTest test, std::span<const testing::RaySet> sets,
                        const std::string& scene_name, std::size_t& hits_seen, bool spatial_splits = false) {
    BuildOptions options = build_options(test);
    options.group<BvhOptions>().spatial_splits = spatial_splits;
    BvhAccel bvh;
    bvh.build(geometry, options);
    const gpu::FlatBvh flat = gpu::flatten_bvh(bvh, geometry);
    const gpu::BvhView bvh_view = flat.view();
    const plucker::PluckerTables tables = plucker::kTables;
    // The walk over the four layouts: with and without the 2:1 rule, with stored and computed boxes.
    PluckerAccel octrees[4];
    for (int variant = 0; variant < 4; ++variant) {
        BuildOptions layout = options;
        layout.group<PluckerOptions>().balanced = variant < 2;
        layout.group<PluckerOptions>().stored_boxes = variant % 2 == 0;
        octrees[variant].build(geometry, layout);
    }
    const char* test_name = test == TriangleTest::Watertight ? "watertight" : "moller";
    for (const testing::RaySet& set : sets) {
        std::vector<Hit> expected_bvh(set.rays.size());
        bvh.intersect(set.rays, expected_bvh);
        hits_seen += count_hits(expected_bvh);
        const std::string where = scene_name + ", " + set.name + ", " + test_name + ": ";
        std::string first;

        expect_walk_agrees<TriangleTestT, gpu::WalkLayout<true, true>>(octrees[0], tables, set, where);
        expect_walk_agrees<TriangleTestT, gpu::WalkLayout<true, false>>(octrees[1], tables, set, where);
        expect_walk_agrees<TriangleTestT, gpu::WalkLayout<false, true>>(octrees[2], tables, set, where);
        expect_walk_agrees<TriangleTestT, gpu::WalkLayout<false, false>>(octrees[3], tables, set, where);

        const auto while_while = trace_each(set.rays, bvh.bounds(), [&](const Ray& ray) {
            return gpu::trace_bvh<false, TriangleTestT>(bvh_view, ray, gpu::LoneLane{});
        });
        EXPECT_EQ(count_differences(expected_bvh, while_while, first), 0u)
            << where << "while-while, " << first;

        const auto speculative_alone = trace_each(set.rays, bvh.bounds(), [&](const Ray& ray) {
            return gpu::trace_bvh<true, TriangleTestT>(bvh_view, ray, gpu::LoneLane{});
        });
        EXPECT_EQ(count_differences(expected_bvh, speculative_alone, first), 0u)
            << where << "speculative while-while (lone lane), " << first;

        const auto speculative_postponing = trace_each(set.rays, bvh.bounds(), [&](const Ray& ray) {
            return gpu::trace_bvh<true, TriangleTestT>(bvh_view, ray, gpu::OtherLanesSearching{});
        });
        EXPECT_EQ(count_differences(expected_bvh, speculative_postponing, first), 0u)
            << where << "speculative while-while (postponing), " << first;

        std::vector<std::uint8_t> expected_occlusion(set.rays.size());
        bvh.occluded(set.rays, expected_occlusion);
        const auto while_while_occlusion = occlusion_each(set.rays, bvh.bounds(), [&](const Ray& ray) {
            return gpu::trace_bvh<false, TriangleTestT, true>(bvh_view, ray, gpu::LoneLane{});
        });
        EXPECT_EQ(count_differences(expected_occlusion, while_while_occlusion), 0u)
            << where << "while-while's occlusion";
        const auto speculative_occlusion = occlusion_each(set.rays, bvh.bounds(), [&](const Ray& ray) {
            return gpu::trace_bvh<true, TriangleTestT, true>(bvh_view, ray, gpu::OtherLanesSearching{});
        });
        EXPECT_EQ(count_differences(expected_occlusion, speculative_occlusion), 0u)
            << where << "speculative while-while's occlusion (postponing)";
    }
}

TEST(CudaPorts, AgreeBitForBitWithTheCpuStructuresOnTheTestScenes) {
    for (const bool spatial_splits : {false, true}) {
        std::size_t hits_seen = 0;
        for (const TestScene& scene : make_triangle_scenes()) {
            const std::vector<testing::RaySet> sets = ray_sets_for(scene);
            expect_ports_agree<MollerTrumbore>(scene.geometry(), TriangleTest::MollerTrumbore, sets,
                                               scene.name, hits_seen, spatial_splits);
            expect_ports_agree<Watertight>(scene.geometry(), TriangleTest::Watertight, sets, scene.name,
                                           hits_seen, spatial_splits);
        }
        // The comparison means something only if the rays hit: most scenes are hit by a good share of them.
        EXPECT_GT(hits_seen, 20000u);
    }
}

TEST_F(BunnyCanonicalView, PortsAgreeBitForBit) {
    std::size_t hits_seen = 0;
    expect_ports_agree<MollerTrumbore>(geometry(), TriangleTest::MollerTrumbore, sets(), "bunny", hits_seen);
    EXPECT_GT(hits_seen, kSide * kSide / 10u);
}

// The heatmap's counts: the walk enters the leaves the CPU walk enters, one by one; the BVH traversals count
// each inner node fetched and each leaf tested, at least one node for any ray that hits.
TEST(CudaPorts, StepCountsAreTheCpuWalksLeaves) {
    const TestScene scene = make_triangle_scenes()[0];
    PluckerAccel plucker;
    plucker.build(scene.geometry(), {});
    BvhAccel bvh;
    bvh.build(scene.geometry(), {});
    const plucker::PluckerView view = gpu::plucker_view(plucker.layout());
    const gpu::FlatBvh flat = gpu::flatten_bvh(bvh, scene.geometry());
    const plucker::PluckerTables tables = plucker::kTables;
    const testing::RaySet set = testing::random_rays(scene.geometry().bounds(), 2000, 21);
    // Without the 2:1 rule the count takes in the inner cells a link descends, as the CPU walk counts them.
    BuildOptions unconstrained;
    unconstrained.group<PluckerOptions>().balanced = false;
    PluckerAccel unconstrained_plucker;
    unconstrained_plucker.build(scene.geometry(), unconstrained);
    const plucker::PluckerView unconstrained_view = gpu::plucker_view(unconstrained_plucker.layout());
    std::uint64_t leaves = 0, unconstrained_steps = 0;
    for (const Ray& ray : set.rays) {
        Hit expected;
        TraversalCounters counters, unconstrained_counters;
        plucker.intersect({&ray, 1}, {&expected, 1}, &counters);
        unconstrained_plucker.intersect({&ray, 1}, {&expected, 1}, &unconstrained_counters);
        gpu::CountSteps walk_steps, unconstrained_walk_steps, bvh_steps;
        (void)gpu::trace_plucker<MollerTrumbore, gpu::SeedLayout>(view, tables, ray, walk_steps);
        ASSERT_EQ(walk_steps.steps, counters.nodes_visited);
        (void)gpu::trace_plucker<MollerTrumbore, gpu::WalkLayout<false, true>>(unconstrained_view, tables,
                                                                               ray, unconstrained_walk_steps);
        ASSERT_EQ(unconstrained_walk_steps.steps, unconstrained_counters.nodes_visited);
        leaves += walk_steps.steps;
        unconstrained_steps += unconstrained_walk_steps.steps;
        const Hit hit = gpu::trace_bvh<true, MollerTrumbore>(flat.view(), ray, gpu::LoneLane{}, bvh_steps);
        if (hit.hit()) {
            EXPECT_GE(bvh_steps.steps, 2u);
        }
    }
    EXPECT_GT(leaves, set.rays.size());
    EXPECT_GT(unconstrained_steps, set.rays.size());
}

// The kernels number a frame's rays by warp-sized tiles: every pixel must get exactly one ray, also when the
// film is not a whole number of tiles.
TEST(CudaPorts, FrameTilesCoverEveryPixelOnce) {
    for (const auto& [width, height] : {std::pair{64, 32}, std::pair{37, 11}, std::pair{1, 1}}) {
        CameraFrame frame;
        frame.width = width, frame.height = height;
        std::vector<int> rays_per_pixel(static_cast<std::size_t>(width * height), 0);
        const std::uint32_t count = gpu::frame_ray_count(frame);
        EXPECT_EQ(count % 32u, 0u);
        for (std::uint32_t index = 0; index < count; ++index) {
            int x = -1, y = -1;
            if (gpu::frame_pixel(frame, index, x, y))
                ++rays_per_pixel[static_cast<std::size_t>(y * width + x)];
        }
        for (const int rays : rays_per_pixel)
            ASSERT_EQ(rays, 1) << width << "x" << height;
    }
}

// Also with spatial splits, on the triangle soup, whose large triangles they cut: a triangle then sits in
// several leaves, and the flattened BVH copies it into each.
void expect_flat_bvh_keeps_every_child_box_and_reference(const TestScene& scene, bool spatial_splits) {
    BuildOptions options;
    options.group<BvhOptions>().spatial_splits = spatial_splits;
    BvhAccel bvh;
    bvh.build(scene.geometry(), options);
    if (spatial_splits) {
        EXPECT_GT(bvh.prim_indices().size(), scene.triangles.size());
    }
    const gpu::FlatBvh flat = gpu::flatten_bvh(bvh, scene.geometry());
    std::size_t inner = 0;
    for (const BvhNode& node : bvh.nodes())
        inner += node.is_leaf() ? 0 : 1;
    ASSERT_EQ(flat.nodes.size(), inner);
    // Walk both trees together: every child's box, leaf range and triangle equal the CPU's.
    std::vector<std::pair<std::uint32_t, std::int32_t>> pending = {{0u, 0}};
    std::size_t references = 0;
    while (!pending.empty()) {
        const auto [cpu, gpu_node] = pending.back();
        pending.pop_back();
        const gpu::AilaLaineNode& node = flat.nodes[static_cast<std::size_t>(gpu_node)];
        const std::uint32_t children[2] = {cpu + 1, bvh.nodes()[cpu].offset};
        for (int c = 0; c < 2; ++c) {
            const BvhNode& child = bvh.nodes()[children[c]];
            const Vec3f lo = c == 0 ? Vec3f(node.c0_lo_x, node.c0_lo_y, node.c0_lo_z)
                                    : Vec3f(node.c1_lo_x, node.c1_lo_y, node.c1_lo_z);
            const Vec3f hi = c == 0 ? Vec3f(node.c0_hi_x, node.c0_hi_y, node.c0_hi_z)
                                    : Vec3f(node.c1_hi_x, node.c1_hi_y, node.c1_hi_z);
            EXPECT_EQ(lo, child.lo);
            EXPECT_EQ(hi, child.hi);
            if (!child.is_leaf()) {
                ASSERT_GE(node.child[c], 0);
                pending.push_back({children[c], node.child[c]});
                continue;
            }
            ASSERT_LT(node.child[c], 0);
            ASSERT_EQ(gpu::leaf_first(node.child[c]), child.offset);
            ASSERT_EQ(gpu::leaf_count(node.child[c]), child.prim_count);
            for (std::uint32_t r = child.offset; r < child.offset + child.prim_count; ++r) {
                const std::uint32_t prim = bvh.prim_indices()[r];
                EXPECT_EQ(flat.triangles[r].prim, prim);
                EXPECT_EQ(std::memcmp(&flat.triangles[r].triangle, &scene.triangles[prim], sizeof(Triangle)),
                          0);
                ++references;
            }
        }
    }
    EXPECT_EQ(references, bvh.prim_indices().size());
}

TEST(CudaPorts, FlatBvhKeepsEveryChildBoxAndReference) {
    expect_flat_bvh_keeps_every_child_box_and_reference(make_triangle_scenes()[0], false);
    expect_flat_bvh_keeps_every_child_box_and_reference(make_triangle_scenes()[1], true);
}

TEST(CudaPorts, RefuseWhatTheKernelsDoNotTrace) {
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const std::vector<Sphere> spheres = {{{0, 0, 2}, 0.5f, 0}};
    const Geometry with_spheres{triangles, spheres};
    BvhAccel bvh;
    bvh.build(with_spheres, {});
    EXPECT_THROW((void)gpu::flatten_bvh(bvh, with_spheres), std::invalid_argument);
    PluckerAccel plucker;
    plucker.build(with_spheres, {});
    EXPECT_THROW((void)gpu::plucker_view(plucker.layout()), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
