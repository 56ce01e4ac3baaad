// Deterministic parallel builds (STYLE.md, habit 7; docs/accel/parallel-build.md): every structure built
// inside a 1-thread task arena and inside a 4-thread one must be the same structure, array for array, and so
// give the same answers bit for bit. The scenes are large enough to take every parallel path of the builds
// (subtrees and blocks of more than a few thousand references), and the second one makes the grid exceed
// its reference budget, so that its coarsening runs in parallel too.
#include <gtest/gtest.h>

#include <tbb/task_arena.h>
#include <array>
#include <bit>
#include <cstring>
#include <memory>
#include <random>
#include <utility>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/grid.hpp"
#include "accel/kdtree.hpp"
#include "accel/octree_build.hpp"
#include "accel/plucker/plucker.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::TestScene;

constexpr int kManyThreads = 4;

TestScene mixed_scene() {
    TestScene scene{"icosphere, soup and spheres", {}, {}};
    make_icosphere(5, {0, 0, 0}, 1.0f).append_triangles(scene.triangles);
    std::mt19937 rng(6);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    auto point = [&](float scale) { return Vec3f(unit(rng), unit(rng), unit(rng)) * scale; };
    for (int i = 0; i < 6000; ++i) {
        const Vec3f base = point(4.0f) - Vec3f(2.0f);
        const float size = i % 10 == 0 ? 1.0f : 0.05f;
        scene.triangles.push_back(
            {base, base + point(size) - Vec3f(size / 2), base + point(size) - Vec3f(size / 2)});
    }
    for (int i = 0; i < 100; ++i)
        scene.spheres.push_back({point(4.0f) - Vec3f(2.0f), 0.01f + 0.1f * unit(rng), 0});
    return scene;
}

// Large triangles crossing the whole box: the grid's first resolution needs more references than its budget.
TestScene overlapping_scene() {
    TestScene scene{"large overlapping triangles", {}, {}};
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    auto point = [&] { return Vec3f(unit(rng), unit(rng), unit(rng)) * 10.0f; };
    for (int i = 0; i < 3000; ++i)
        scene.triangles.push_back({point(), point(), point()});
    return scene;
}

std::vector<Ray> random_rays(const Box3f& bounds, std::size_t count) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const Vec3f extent = bounds.extent();
    auto inside = [&] {
        return bounds.lo + Vec3f(unit(rng) * extent.x, unit(rng) * extent.y, unit(rng) * extent.z);
    };
    std::vector<Ray> rays;
    for (std::size_t i = 0; i < count; ++i) {
        // Half from outside the box towards a point inside, half from inside in a random direction.
        const Vec3f target = inside();
        const Vec3f origin = i % 2 ? bounds.center() + (inside() - bounds.center()) * 3.0f : inside();
        const Vec3f direction = i % 2 ? target - origin : inside() - inside();
        rays.push_back({origin, direction, 0.0f, kInfinity});
    }
    return rays;
}

template <class Build>
auto in_arena(int threads, Build&& build) {
    tbb::task_arena arena(threads);
    return arena.execute(std::forward<Build>(build));
}

// `accel` built inside an arena of `threads` threads.
template <class AccelT>
std::unique_ptr<AccelT> built_with_threads(std::unique_ptr<AccelT> accel, const Geometry& geometry,
                                           const BuildOptions& options, int threads) {
    in_arena(threads, [&] { accel->build(geometry, options); });
    return accel;
}

// Every figure but the build time, the values bit for bit.
void expect_same_stats(const AccelStats& one, const AccelStats& many) {
    EXPECT_EQ(one.primitives, many.primitives);
    ASSERT_EQ(one.figures.size(), many.figures.size());
    for (std::size_t k = 0; k < one.figures.size(); ++k) {
        EXPECT_EQ(one.figures[k].key, many.figures[k].key);
        EXPECT_EQ(std::bit_cast<std::uint64_t>(one.figures[k].value),
                  std::bit_cast<std::uint64_t>(many.figures[k].value))
            << one.figures[k].key;
    }
    EXPECT_EQ(one.memory_by_array, many.memory_by_array);
}

// The closest hits and occlusion answers, compared bit for bit (t, u and v as bits, not as floats).
void expect_same_answers(const Accel& one, const Accel& many, std::span<const Ray> rays) {
    std::vector<Hit> hits_one(rays.size()), hits_many(rays.size());
    one.intersect(rays, hits_one);
    many.intersect(rays, hits_many);
    std::size_t differing = 0, hit_count = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        differing += std::memcmp(&hits_one[i], &hits_many[i], sizeof(Hit)) != 0 ? 1 : 0;
        hit_count += hits_one[i].hit() ? 1 : 0;
    }
    EXPECT_EQ(differing, 0u);
    EXPECT_GT(hit_count, rays.size() / 10);  // the rays do reach the geometry
    std::vector<std::uint8_t> occluded_one(rays.size()), occluded_many(rays.size());
    one.occluded(rays, occluded_one);
    many.occluded(rays, occluded_many);
    EXPECT_EQ(occluded_one, occluded_many);
}

void expect_same_structure(std::string_view name, const TestScene& scene, const BuildOptions& options = {}) {
    SCOPED_TRACE(scene.name);
    const Geometry geometry = scene.geometry();
    const auto one = built_with_threads(make_accel(name), geometry, options, 1);
    const auto many = built_with_threads(make_accel(name), geometry, options, kManyThreads);
    expect_same_stats(one->stats(), many->stats());
    EXPECT_EQ(one->memory_bytes(), many->memory_bytes());
    expect_same_answers(*one, *many, random_rays(geometry.bounds(), 5000));
}

class ParallelBuild : public ::testing::TestWithParam<std::string> {};

TEST_P(ParallelBuild, OneAndManyThreadsGiveTheSameStructureAndAnswers) {
    expect_same_structure(GetParam(), mixed_scene());
}

INSTANTIATE_TEST_SUITE_P(Structures, ParallelBuild,
                         ::testing::Values("grid", "octree", "plucker", "kdtree", "bvh"));

TEST(ParallelBuildArrays, BvhWithSpatialSplitsIsTheSame) {
    BuildOptions options;
    options.group<BvhOptions>().spatial_splits = true;
    expect_same_structure("bvh", mixed_scene(), options);
    expect_same_structure("bvh8", mixed_scene(), options);
}

TEST(ParallelBuildArrays, GridCoarsenedPastItsBudgetIsTheSame) {
    const TestScene scene = overlapping_scene();
    const Geometry geometry = scene.geometry();
    BuildOptions options;
    options.group<GridOptions>().density = 3.0f;  // 81000 cells, each triangle crossing hundreds of them
    GridAccel grid;
    grid.build(geometry, options);
    const auto first_try = GridAccel::choose_resolution(geometry.bounds(), geometry.size(),
                                                        options.group<GridOptions>().density);
    ASSERT_LT(grid.resolution()[0] * grid.resolution()[1] * grid.resolution()[2],
              first_try[0] * first_try[1] * first_try[2]);  // the budget was exceeded, the grid coarsened
    expect_same_structure("grid", scene, options);
}

// The arrays themselves, where the classes show them: plain data, compared byte for byte.
template <class T, class Allocator>
void expect_same_bytes(const std::vector<T, Allocator>& one, const std::vector<T, Allocator>& many) {
    ASSERT_EQ(one.size(), many.size());
    EXPECT_EQ(std::memcmp(one.data(), many.data(), one.size() * sizeof(T)), 0);
}

TEST(ParallelBuildArrays, GridCellsListTheSamePrimitives) {
    const TestScene scene = mixed_scene();
    const Geometry geometry = scene.geometry();
    const auto one = built_with_threads(std::make_unique<GridAccel>(), geometry, {}, 1);
    const auto many = built_with_threads(std::make_unique<GridAccel>(), geometry, {}, kManyThreads);
    ASSERT_EQ(one->resolution(), many->resolution());
    const auto [nx, ny, nz] = one->resolution();
    std::size_t differing = 0;
    for (int z = 0; z < nz; ++z) {
        for (int y = 0; y < ny; ++y) {
            for (int x = 0; x < nx; ++x) {
                const auto a = one->cell_primitives(x, y, z), b = many->cell_primitives(x, y, z);
                differing += std::equal(a.begin(), a.end(), b.begin(), b.end()) ? 0 : 1;
            }
        }
    }
    EXPECT_EQ(differing, 0u);
}

TEST(ParallelBuildArrays, OctreeCellsAndReferences) {
    const TestScene scene = mixed_scene();
    const Geometry geometry = scene.geometry();
    OctreeOptions options;
    options.max_depth = 9;
    const auto build = [&] { return build_octree(geometry, options); };
    const Octree one = in_arena(1, build), many = in_arena(kManyThreads, build);
    // 26k primitives: the root's split and the first levels' subtrees take the parallel paths.
    ASSERT_GT(one.cells.size(), 1000u);
    expect_same_bytes(one.cells, many.cells);
    EXPECT_EQ(one.references, many.references);
}

TEST(ParallelBuildArrays, KdTreeNodesAndReferences) {
    const TestScene scene = mixed_scene();
    const Geometry geometry = scene.geometry();
    const auto build = [&] { return build_kdtree(geometry, KdTreeOptions{}); };
    const KdTreeData one = in_arena(1, build), many = in_arena(kManyThreads, build);
    expect_same_bytes(one.nodes, many.nodes);
    EXPECT_EQ(one.references, many.references);
}

// The collapse numbers the leaves' triangle blocks in one pass and writes them in parallel: leaves of one
// block, and the default's merged leaves of several.
TEST(ParallelBuildArrays, Bvh8NodesAndTriangleBlocks) {
    const TestScene scene = mixed_scene();
    const Geometry geometry = scene.geometry();
    // Each case with more leaves than one task of the block writing takes (at most 1,024 each).
    const std::array<std::pair<int, std::size_t>, 2> cases = {
        {{1, 4096}, {BvhOptions{}.wide_leaf_size, 1024}}};
    for (const auto& [wide_leaf_size, least_leaves] : cases) {
        BuildOptions options;
        options.group<BvhOptions>().wide_leaf_size = wide_leaf_size;
        const auto one = built_with_threads(std::make_unique<Bvh8Accel>(), geometry, options, 1);
        const auto many = built_with_threads(std::make_unique<Bvh8Accel>(), geometry, options, kManyThreads);
        std::size_t leaves = 0;
        for (const WideBvhNode<8>& node : one->nodes()) {
            for (int slot = 0; slot < 8; ++slot)
                leaves += node.prim_count[slot] != 0 ? 1 : 0;
        }
        ASSERT_GT(leaves, least_leaves) << wide_leaf_size;
        expect_same_bytes(one->nodes(), many->nodes());
        expect_same_bytes(one->blocks(), many->blocks());
    }
}

TEST(ParallelBuildArrays, PluckerLayoutArrays) {
    const TestScene scene = mixed_scene();
    const Geometry geometry = scene.geometry();
    const auto one = built_with_threads(std::make_unique<PluckerAccel>(), geometry, {}, 1);
    const auto many = built_with_threads(std::make_unique<PluckerAccel>(), geometry, {}, kManyThreads);
    const plucker::PluckerLayout& a = one->layout();
    const plucker::PluckerLayout& b = many->layout();
    EXPECT_EQ(a.cells, b.cells);
    EXPECT_EQ(a.locate, b.locate);
    EXPECT_EQ(a.cube_map.level, b.cube_map.level);
    EXPECT_EQ(a.cube_map.texels, b.cube_map.texels);
    expect_same_bytes(a.primitives, b.primitives);
    expect_same_bytes(a.boxes, b.boxes);
}

}  // namespace
}  // namespace lancer
