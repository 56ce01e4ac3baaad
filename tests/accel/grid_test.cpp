// The regular grid: the resolution rule, references exactly where primitives overlap, consistent stats, and
// the 3D-DDA walk on the rays that break it (a hit lying beyond the cell it was found in, origins inside the
// grid, on cell planes and on grid lines, rays along grid planes), each against brute force.
#include "accel/grid.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "accel/brute.hpp"
#include "accel/build_util.hpp"
#include "accel/kdtree.hpp"
#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

// Small triangles scattered in [0, size]^3, plus two at opposite corners so that the box is that cube.
std::vector<Triangle> scattered_triangles(std::size_t count, float size, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> coordinate(0.0f, size), offset(-0.05f, 0.05f);
    std::vector<Triangle> triangles = {
        {{0, 0, 0}, {0.1f, 0, 0}, {0, 0.1f, 0}},
        {{size, size, size}, {size - 0.1f, size, size}, {size, size - 0.1f, size}}};
    while (triangles.size() < count) {
        const Vec3f a(coordinate(rng), coordinate(rng), coordinate(rng));
        const Vec3f b = min(max(a + Vec3f(offset(rng), offset(rng), offset(rng)), Vec3f(0.0f)), Vec3f(size));
        const Vec3f c = min(max(a + Vec3f(offset(rng), offset(rng), offset(rng)), Vec3f(0.0f)), Vec3f(size));
        triangles.push_back({a, b, c});
    }
    return triangles;
}

std::size_t cell_count(const GridAccel& grid) {
    const std::array<int, 3> resolution = grid.resolution();
    return static_cast<std::size_t>(resolution[0]) * resolution[1] * resolution[2];
}

// Closest hit and occlusion against brute force for both triangle tests; returns the hits found, so that a
// caller can check the rays were not all misses.
std::size_t expect_agreement_with_brute(const Geometry& geometry, std::span<const Ray> rays,
                                        const std::string& what, float density = 1.0f) {
    std::size_t hits_found = 0;
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        BuildOptions options = build_options(test);
        options.group<GridOptions>().density = density;
        BruteAccel brute;
        GridAccel grid;
        brute.build(geometry, options);
        grid.build(geometry, options);
        std::vector<Hit> expected(rays.size()), actual(rays.size());
        brute.intersect(rays, expected);
        grid.intersect(rays, actual);
        const Agreement closest = compare_hits(rays, expected, actual);
        EXPECT_EQ(closest.mismatches, 0u) << what << ": " << closest.summary();
        std::vector<std::uint8_t> occluded(rays.size());
        grid.occluded(rays, occluded);
        const Agreement any = compare_occlusion(rays, expected, occluded);
        EXPECT_EQ(any.mismatches, 0u) << what << ": " << any.summary();
        hits_found += closest.hits;
    }
    return hits_found;
}

// ---------------------------------------------------------------------------------------------------------
// Resolution

TEST(Grid, CubeGetsAboutTheCubeRootOfNCellsPerAxis) {
    for (const auto& [count, expected] : {std::pair<std::size_t, int>{1000, 10}, {8000, 20}, {27000, 30}}) {
        const std::array<int, 3> resolution =
            GridAccel::choose_resolution({{0, 0, 0}, {5, 5, 5}}, count, 1.0f);
        EXPECT_EQ(resolution, (std::array<int, 3>{expected, expected, expected})) << count;
    }
    // The built grid over N triangles whose box is a cube.
    const std::vector<Triangle> triangles = scattered_triangles(1000, 4.0f, 1);
    GridAccel grid;
    grid.build({triangles, {}}, {});
    EXPECT_EQ(grid.resolution(), (std::array<int, 3>{10, 10, 10}));
    // The density scales cells per axis.
    EXPECT_EQ(GridAccel::choose_resolution({{0, 0, 0}, {1, 1, 1}}, 1000, 2.0f),
              (std::array<int, 3>{20, 20, 20}));
}

TEST(Grid, CellsAreCubicAndSharedInProportionToTheExtents) {
    // Box 4 x 2 x 1 with 512 primitives: side cbrt(8 / 512) = 1/4.
    EXPECT_EQ(GridAccel::choose_resolution({{0, 0, 0}, {4, 2, 1}}, 512, 1.0f),
              (std::array<int, 3>{16, 8, 4}));
    EXPECT_EQ(GridAccel::choose_resolution({{0, 0, 0}, {1, 1, 100}}, 100, 1.0f),
              (std::array<int, 3>{1, 1, 100}));
}

TEST(Grid, FlatBoxGetsOneCellOnItsFlatAxis) {
    // 3200 triangles in the plane z = 0: the cells go to x and y, about sqrt(N) each.
    const std::vector<Triangle> triangles = testing::planar_grid_triangles(40);
    GridAccel grid;
    grid.build({triangles, {}}, {});
    const std::array<int, 3> resolution = grid.resolution();
    EXPECT_EQ(resolution[2], 1);
    EXPECT_NEAR(resolution[0], std::sqrt(3200.0), 1.0);
    EXPECT_EQ(resolution[0], resolution[1]);
    // Flat along y, and a box thinner than one cubic cell on y.
    EXPECT_EQ(GridAccel::choose_resolution({{0, 0, 0}, {10, 0, 10}}, 100, 1.0f)[1], 1);
    EXPECT_EQ(GridAccel::choose_resolution({{0, 0, 0}, {10, 0.01f, 10}}, 100, 1.0f)[1], 1);
    // A box that is a single point: one cell.
    EXPECT_EQ(GridAccel::choose_resolution({{1, 1, 1}, {1, 1, 1}}, 100, 1.0f), (std::array<int, 3>{1, 1, 1}));
}

TEST(Grid, CellCountIsCapped) {
    for (float density : {8.0f, 100.0f, 1e6f}) {
        const std::array<int, 3> resolution =
            GridAccel::choose_resolution({{0, 0, 0}, {3, 1, 2}}, 10, density);
        EXPECT_LE(static_cast<double>(resolution[0]) * resolution[1] * resolution[2], 64.0 * 10 + 64)
            << density;
        EXPECT_GT(static_cast<double>(resolution[0]) * resolution[1] * resolution[2], 64.0 * 10 / 4)
            << density;
    }
}

TEST(Grid, DensityMustBePositiveAndFinite) {
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    for (float density : {0.0f, -1.0f, std::numeric_limits<float>::quiet_NaN(), kInfinity}) {
        BuildOptions options;
        options.group<GridOptions>().density = density;
        GridAccel grid;
        EXPECT_THROW(grid.build({triangles, {}}, options), std::invalid_argument) << density;
    }
}

// ---------------------------------------------------------------------------------------------------------
// Structure

// Every primitive is listed by exactly the cells whose reference box it overlaps, once, in ascending order;
// a cell farther than one cell from a primitive's bounds never lists it; the cells tile the entry box.
void expect_valid_grid(const GridAccel& grid, const Geometry& geometry) {
    const std::array<int, 3> resolution = grid.resolution();
    // The outer cells reach the entry box, the scene box grown by the tolerance (finding 15).
    const Box3f entry_box = geometry.bounds().grown(geometric_tolerance(geometry.bounds()));
    ASSERT_EQ(grid.cell_box(0, 0, 0).lo, entry_box.lo);
    ASSERT_EQ(grid.cell_box(resolution[0] - 1, resolution[1] - 1, resolution[2] - 1).hi, entry_box.hi);
    std::vector<std::size_t> cells_per_prim(geometry.size(), 0);
    for (int z = 0; z < resolution[2]; ++z) {
        for (int y = 0; y < resolution[1]; ++y) {
            for (int x = 0; x < resolution[0]; ++x) {
                const Box3f cell = grid.cell_box(x, y, z);
                ASSERT_TRUE(x == 0 || cell.lo.x == grid.cell_box(x - 1, y, z).hi.x);
                ASSERT_TRUE(y == 0 || cell.lo.y == grid.cell_box(x, y - 1, z).hi.y);
                ASSERT_TRUE(z == 0 || cell.lo.z == grid.cell_box(x, y, z - 1).hi.z);
                const std::span<const std::uint32_t> listed = grid.cell_primitives(x, y, z);
                ASSERT_TRUE(std::is_sorted(listed.begin(), listed.end()));
                ASSERT_TRUE(std::adjacent_find(listed.begin(), listed.end()) == listed.end());
                const Box3f reference_box = grid.reference_box(x, y, z);
                const Vec3f cell_extent = cell.extent();
                for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
                    const bool is_listed = std::binary_search(listed.begin(), listed.end(), prim);
                    ASSERT_EQ(is_listed, primitive_overlaps_box(geometry, prim, reference_box))
                        << "primitive " << prim << ", cell " << x << " " << y << " " << z;
                    const Box3f prim_bounds = primitive_bounds(geometry, prim);
                    const Box3f near_prim{prim_bounds.lo - cell_extent, prim_bounds.hi + cell_extent};
                    ASSERT_FALSE(is_listed && intersection(near_prim, cell).empty())
                        << "far primitive " << prim;
                    cells_per_prim[prim] += is_listed ? 1 : 0;
                }
            }
        }
    }
    for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
        if (primitive_bounds(geometry, prim).empty()) continue;
        ASSERT_GT(cells_per_prim[prim], 0u) << "primitive " << prim << " is in no cell";
    }
}

TEST(Grid, EveryPrimitiveIsListedByEveryCellItOverlapsAndNoOther) {
    const std::vector<Triangle> knot = make_torus_knot(60, 6).triangles();
    const std::vector<Triangle> soup = scattered_triangles(300, 3.0f, 2);
    const std::vector<Sphere> spheres = {{{0.5f, 0.5f, 0.5f}, 0.4f, 0}, {{2.0f, 1.0f, 2.5f}, 0.05f, 0}};
    // A long sliver along the diagonal: its bounds cover every cell, it overlaps few.
    std::vector<Triangle> with_sliver = soup;
    with_sliver.push_back({{0, 0, 0}, {3, 3, 3}, {3, 3, 2.9f}});
    for (const Geometry& geometry :
         {Geometry{knot, {}}, Geometry{soup, spheres}, Geometry{with_sliver, {}}}) {
        for (float density : {0.5f, 1.0f, 2.0f}) {
            BuildOptions options;
            options.group<GridOptions>().density = density;
            GridAccel grid;
            grid.build(geometry, options);
            expect_valid_grid(grid, geometry);
        }
    }
    // The sliver is listed by far fewer cells than its bounds cover.
    GridAccel grid;
    grid.build({with_sliver, {}}, {});
    std::size_t sliver_cells = 0;
    const std::array<int, 3> resolution = grid.resolution();
    for (int z = 0; z < resolution[2]; ++z) {
        for (int y = 0; y < resolution[1]; ++y) {
            for (int x = 0; x < resolution[0]; ++x) {
                const std::span<const std::uint32_t> listed = grid.cell_primitives(x, y, z);
                sliver_cells += std::count(listed.begin(), listed.end(), with_sliver.size() - 1);
            }
        }
    }
    EXPECT_LT(sliver_cells, cell_count(grid) / 4);
}

TEST(Grid, StatsMatchTheArrays) {
    const std::vector<Triangle> triangles = make_torus_knot(200, 8).triangles();
    GridAccel grid;
    grid.build({triangles, {}}, {});
    const AccelStats stats = grid.stats();
    const std::array<int, 3> resolution = grid.resolution();
    std::size_t references = 0, empty = 0, most = 0;
    for (int z = 0; z < resolution[2]; ++z) {
        for (int y = 0; y < resolution[1]; ++y) {
            for (int x = 0; x < resolution[0]; ++x) {
                const std::size_t listed = grid.cell_primitives(x, y, z).size();
                references += listed;
                empty += listed == 0 ? 1 : 0;
                most = std::max(most, listed);
            }
        }
    }
    EXPECT_EQ(stats.primitives, triangles.size());
    EXPECT_EQ(stats.count("cells"), cell_count(grid));
    EXPECT_EQ(stats.count("references"), references);
    EXPECT_EQ(stats.count("empty_cells"), empty);
    EXPECT_EQ(stats.count("max_refs_per_cell"), most);
    EXPECT_DOUBLE_EQ(stats.value("mean_refs_per_cell"),
                     static_cast<double>(references) / static_cast<double>(stats.count("cells") - empty));
    EXPECT_EQ(stats.find("max_depth"), nullptr);  // a grid has no hierarchy, and says none
    // The grid as a one-level tree (MacDonald & Booth 1990) with the kd-tree's default step and test costs:
    // SA(cell) / SA(box) (C_step cells + C_isect references), the cell the box cut by the resolution.
    const KdTreeOptions costs;
    const Box3f& box = grid.bounds();
    double cell_side[3];
    for (int axis = 0; axis < 3; ++axis)
        cell_side[axis] = (static_cast<double>(box.hi[axis]) - box.lo[axis]) / resolution[axis];
    const double cell_area =
        2.0 * (cell_side[0] * cell_side[1] + cell_side[1] * cell_side[2] + cell_side[2] * cell_side[0]);
    const double sah = cell_area / box.surface_area() *
                       (costs.traversal_cost * static_cast<double>(cell_count(grid)) +
                        costs.intersection_cost * static_cast<double>(references));
    EXPECT_NEAR(stats.value("sah_cost"), sah, 1e-5 * sah);
    std::size_t listed_bytes = 0;
    for (const auto& [name, bytes] : stats.memory_by_array)
        listed_bytes += bytes;
    EXPECT_EQ(grid.memory_bytes(), listed_bytes);
    const std::size_t planes = static_cast<std::size_t>(resolution[0] + resolution[1] + resolution[2] + 3);
    EXPECT_EQ(grid.memory_bytes(), (cell_count(grid) + 1) * sizeof(GridAccel::CellOffset) + references * 4 +
                                       planes * sizeof(float));
}

TEST(Grid, BuildIsDeterministic) {
    const std::vector<Triangle> triangles = make_torus_knot(150, 8).triangles();
    GridAccel first, second;
    first.build({triangles, {}}, {});
    second.build({triangles, {}}, {});
    ASSERT_EQ(first.resolution(), second.resolution());
    const std::array<int, 3> resolution = first.resolution();
    for (int z = 0; z < resolution[2]; ++z) {
        for (int y = 0; y < resolution[1]; ++y) {
            for (int x = 0; x < resolution[0]; ++x) {
                const auto a = first.cell_primitives(x, y, z), b = second.cell_primitives(x, y, z);
                ASSERT_TRUE(std::equal(a.begin(), a.end(), b.begin(), b.end()));
            }
        }
    }
}

TEST(Grid, LargeCrossingTrianglesCoarsenTheGridInsteadOfExhaustingMemory) {
    // 200 triangles each cutting the whole box along a plane: at density 4 every one would be listed by a
    // whole slice of cells, about 200 * 550 references, beyond the budget of 64 N + 65536.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> height(0.0f, 1.0f);
    std::vector<Triangle> triangles;
    for (int i = 0; i < 200; ++i) {
        const float a = height(rng), b = height(rng), c = height(rng);
        triangles.push_back({{-1, -1, a}, {3, -1, b}, {-1, 3, c}});
    }
    BuildOptions options;
    options.group<GridOptions>().density = 4.0f;
    GridAccel grid;
    grid.build({triangles, {}}, options);
    EXPECT_LE(grid.stats().count("references"), GridAccel::max_references(triangles.size()));
    const std::array<int, 3> asked = GridAccel::choose_resolution(grid.bounds(), triangles.size(), 4.0f);
    EXPECT_LT(cell_count(grid), static_cast<std::size_t>(asked[0]) * asked[1] * asked[2]);
    expect_valid_grid(grid, {triangles, {}});
    const testing::RaySet set = testing::random_rays(Geometry{triangles, {}}.bounds(), 2000, 8);
    EXPECT_GT(expect_agreement_with_brute({triangles, {}}, set.rays, "crossing triangles", 4.0f), 0u);
}

TEST(Grid, ThousandsOfCoincidentTrianglesStayBounded) {
    std::vector<Triangle> triangles(3000, Triangle{{0, 0, 0}, {1, 0, 0.5f}, {0, 1, 1}});
    GridAccel grid;
    grid.build({triangles, {}}, {});
    EXPECT_LE(grid.stats().count("references"), GridAccel::max_references(triangles.size()));
    const Ray ray{{0.2f, 0.2f, 5.0f}, {0, 0, -1}, 0.0f, kInfinity};
    Hit hit;
    grid.intersect({&ray, 1}, {&hit, 1});
    EXPECT_EQ(hit.prim, 0);  // the tie goes to the smallest index
}

// ---------------------------------------------------------------------------------------------------------
// Traversal

// Triangle A is long and slanted (z = x / 16), listed by the first cell the ray enters though the ray meets
// it only at x = 4; triangle B stands across the ray at x = 2. Fillers in a far corner set the resolution.
struct LongTriangleScene {
    static constexpr std::uint32_t kLong = 0, kBetween = 1;
    std::vector<Triangle> triangles;
    Ray ray{{-1.0f, 0.5f, 0.25f}, {1, 0, 0}, 0.0f, kInfinity};

    explicit LongTriangleScene(bool with_between) {
        triangles.push_back({{0, -1, 0}, {20, -1, 1.25f}, {0, 2, 0}});
        triangles.push_back(with_between ? Triangle{{2, 0, 0}, {2, 1.5f, 0}, {2, 0, 1.2f}}
                                         : Triangle{{19, -1, 1.2f}, {19.01f, -1, 1.2f}, {19, -0.99f, 1.2f}});
        for (int i = 0; i < 98; ++i) {
            const float x = 0.2f * static_cast<float>(i);
            triangles.push_back({{x, -1, 1.2f}, {x + 0.01f, -1, 1.2f}, {x, -0.99f, 1.25f}});
        }
    }
};

// The x index of the cell holding coordinate x on the ray's row.
int cell_along_x(const GridAccel& grid, float x) {
    for (int i = 0; i < grid.resolution()[0]; ++i) {
        const Box3f cell = grid.cell_box(i, 0, 0);
        if (cell.lo.x <= x && x < cell.hi.x) return i;
    }
    return -1;
}

TEST(Grid, HitBeyondItsCellDoesNotEndTheWalk) {
    BuildOptions options;
    options.group<GridOptions>().density = 2.0f;
    const LongTriangleScene scene(true);
    GridAccel grid;
    grid.build({scene.triangles, {}}, options);
    ASSERT_GT(grid.resolution()[0], 8);
    // The ray's row of cells: the cell holding its (y, z).
    int row_y = 0, row_z = 0;
    while (grid.cell_box(0, row_y, 0).hi.y < scene.ray.origin.y)
        ++row_y;
    while (grid.cell_box(0, 0, row_z).hi.z < scene.ray.origin.z)
        ++row_z;
    const std::span<const std::uint32_t> first_cell = grid.cell_primitives(0, row_y, row_z);
    ASSERT_TRUE(std::ranges::find(first_cell, LongTriangleScene::kLong) != first_cell.end());
    ASSERT_TRUE(std::ranges::find(first_cell, LongTriangleScene::kBetween) == first_cell.end());
    const int between_cell = cell_along_x(grid, 2.0f);
    ASSERT_GT(between_cell, 0);
    ASSERT_GT(cell_along_x(grid, 4.0f), between_cell);

    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        options.triangle_test = test;
        grid.build({scene.triangles, {}}, options);
        Hit hit;
        TraversalCounters counters;
        grid.intersect({&scene.ray, 1}, {&hit, 1}, &counters);
        // A, found in the first cell at t = 5, stays the best until B, in between, beats it.
        EXPECT_EQ(hit.prim, static_cast<std::int32_t>(LongTriangleScene::kBetween));
        EXPECT_FLOAT_EQ(hit.t, 3.0f);
        // ... and the walk ends in B's cell, not later.
        EXPECT_EQ(counters.nodes_visited, static_cast<std::uint64_t>(between_cell + 1));
    }
}

TEST(Grid, HitFoundEarlyEndsTheWalkInItsOwnCell) {
    BuildOptions options;
    options.group<GridOptions>().density = 2.0f;
    const LongTriangleScene scene(false);
    GridAccel grid;
    grid.build({scene.triangles, {}}, options);
    Hit hit;
    TraversalCounters counters;
    grid.intersect({&scene.ray, 1}, {&hit, 1}, &counters);
    EXPECT_EQ(hit.prim, static_cast<std::int32_t>(LongTriangleScene::kLong));
    EXPECT_FLOAT_EQ(hit.t, 5.0f);
    EXPECT_EQ(counters.nodes_visited, static_cast<std::uint64_t>(cell_along_x(grid, 4.0f) + 1));
    // A ray that misses everything walks its whole row.
    const Ray above{{-1.0f, 0.5f, 1.24f}, {1, 0, 0}, 0.0f, kInfinity};
    counters = {};
    grid.intersect({&above, 1}, {&hit, 1}, &counters);
    EXPECT_FALSE(hit.hit());
    EXPECT_EQ(counters.nodes_visited, static_cast<std::uint64_t>(grid.resolution()[0]));
}

// Cells crossed by the segment of the ray inside [0, 8]^3 with unit cells, computed apart in double: one
// more than the planes crossed. 0 when the ray misses the box or only grazes it.
int cells_crossed_in_lattice(const Ray& ray) {
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    for (int axis = 0; axis < 3; ++axis) {
        const double o = ray.origin[axis], d = ray.direction[axis];
        if (d == 0.0) {
            if (o <= 0.0 || o >= 8.0) return 0;
            continue;
        }
        const double near_plane = (0.0 - o) / d, far_plane = (8.0 - o) / d;
        t0 = std::max(t0, std::min(near_plane, far_plane));
        t1 = std::min(t1, std::max(near_plane, far_plane));
    }
    if (!(t1 - t0 > 1e-3)) return 0;
    int crossed = 1;
    for (int axis = 0; axis < 3; ++axis) {
        auto cell = [&](double t) {
            return std::clamp(static_cast<int>(std::floor(ray.origin[axis] + t * ray.direction[axis])), 0, 7);
        };
        crossed += std::abs(cell(t1) - cell(t0));
    }
    return crossed;
}

TEST(Grid, WalkStartsAtTheEntryAndEntersEachCellOnce) {
    // 512 triangles packed in the corner cell (0, 0, 0) and one in the far corner: an 8^3 grid of unit cells
    // that a ray avoiding both corners crosses without a hit, from its entry to its exit.
    std::vector<Triangle> triangles = {{{8, 8, 8}, {7.9f, 8, 8}, {8, 7.9f, 8}}};
    for (int i = 0; i < 511; ++i) {
        const float offset = 0.001f * static_cast<float>(i);
        triangles.push_back({{offset, 0, 0}, {offset + 0.1f, 0, 0.1f}, {offset, 0.1f, 0}});
    }
    GridAccel grid;
    grid.build({triangles, {}}, {});
    ASSERT_EQ(grid.resolution(), (std::array<int, 3>{8, 8, 8}));
    std::mt19937 rng(14);
    std::uniform_real_distribution<float> around(-20.0f, 28.0f), inside(0.0f, 8.0f);
    std::size_t checked = 0;
    for (int i = 0; i < 3000; ++i) {
        const Vec3f origin = i % 3 ? Vec3f(around(rng), around(rng), around(rng))
                                   : Vec3f(inside(rng), inside(rng), inside(rng));
        Vec3f direction = Vec3f(inside(rng), inside(rng), inside(rng)) - origin;
        if (i % 5 == 0) direction[i % 3] = 0.0f;
        const Ray ray{origin, direction, 0.0f, kInfinity};
        const int expected = cells_crossed_in_lattice(ray);
        Hit hit;
        TraversalCounters counters;
        grid.intersect({&ray, 1}, {&hit, 1}, &counters);
        if (hit.hit() || expected == 0) continue;
        ++checked;
        ASSERT_EQ(counters.nodes_visited, static_cast<std::uint64_t>(expected)) << "ray " << i;
    }
    EXPECT_GT(checked, 1500u);
}

// An 8 x 8 x 8 lattice of unit cells (the box is [0, 8]^3 and N = 512), with triangles lying in the cell
// planes and along grid lines, so that rays can start exactly on planes, lines and corners.
std::vector<Triangle> lattice_triangles() {
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> corner(0, 7);
    std::uniform_real_distribution<float> coordinate(0.0f, 8.0f), offset(-0.6f, 0.6f);
    std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{8, 8, 8}, {7, 8, 8}, {8, 7, 8}}};
    while (triangles.size() < 512) {
        const Vec3f a(static_cast<float>(corner(rng)), static_cast<float>(corner(rng)),
                      static_cast<float>(corner(rng)));
        switch (triangles.size() % 3) {
            case 0:  // in the plane z = k, edges along grid lines
                triangles.push_back({a, a + Vec3f(1, 0, 0), a + Vec3f(0, 1, 0)});
                break;
            case 1:  // in the plane x = i, across a cell face diagonal
                triangles.push_back({a, a + Vec3f(0, 1, 1), a + Vec3f(0, 0, 1)});
                break;
            default: {  // anywhere
                const Vec3f p(coordinate(rng), coordinate(rng), coordinate(rng));
                const Vec3f q =
                    min(max(p + Vec3f(offset(rng), offset(rng), offset(rng)), Vec3f(0)), Vec3f(8));
                const Vec3f r =
                    min(max(p + Vec3f(offset(rng), offset(rng), offset(rng)), Vec3f(0)), Vec3f(8));
                triangles.push_back({p, q, r});
            }
        }
    }
    return triangles;
}

TEST(Grid, LatticeHasUnitCells) {
    const std::vector<Triangle> triangles = lattice_triangles();
    GridAccel grid;
    grid.build({triangles, {}}, {});
    ASSERT_EQ(grid.resolution(), (std::array<int, 3>{8, 8, 8}));
    EXPECT_EQ(grid.cell_box(3, 4, 5).lo, Vec3f(3, 4, 5));
    EXPECT_EQ(grid.cell_box(3, 4, 5).hi, Vec3f(4, 5, 6));
}

TEST(Grid, RaysStartingOnCellPlanesLinesAndCorners) {
    const std::vector<Triangle> triangles = lattice_triangles();
    std::mt19937 rng(12);
    std::uniform_int_distribution<int> lattice(0, 8);
    std::uniform_real_distribution<float> coordinate(0.0f, 8.0f);
    std::normal_distribution<float> gaussian;
    auto integer = [&] { return static_cast<float>(lattice(rng)); };
    std::vector<Ray> rays;
    // Corners of cells (and of the box), through other corners (the DDA's three-way ties) or anywhere.
    for (int i = 0; i < 1500; ++i) {
        const Vec3f origin(integer(), integer(), integer());
        const Vec3f direction = i % 2 ? Vec3f(integer(), integer(), integer()) - origin
                                      : Vec3f(gaussian(rng), gaussian(rng), gaussian(rng));
        rays.push_back({origin, direction, 0.0f, kInfinity});
    }
    // On one cell plane, crossing it or running inside it (a zero component); on a grid line, along it.
    for (int i = 0; i < 3000; ++i) {
        const int axis = i % 3;
        Vec3f origin(coordinate(rng), coordinate(rng), coordinate(rng));
        origin[axis] = integer();
        Vec3f direction(gaussian(rng), gaussian(rng), gaussian(rng));
        if (i % 4 == 1) direction[axis] = 0.0f;  // along the plane
        if (i % 4 == 2) {                        // along the grid line of two planes
            origin[(axis + 1) % 3] = integer();
            direction = Vec3f(0.0f);
            direction[(axis + 2) % 3] = i % 8 < 4 ? 1.0f : -1.0f;
        }
        rays.push_back({origin, direction, 0.0f, kInfinity});
    }
    EXPECT_GT(expect_agreement_with_brute({triangles, {}}, rays, "lattice"), rays.size());
}

TEST(Grid, RaysStartingInsideTheGrid) {
    const std::vector<Triangle> triangles = make_torus_knot(150, 8).triangles();
    const std::vector<Sphere> spheres = {{{0, 0, 0}, 0.3f, 0}, {{1, 1, 0}, 0.1f, 0}};
    const Geometry geometry{triangles, spheres};
    const Box3f bounds = geometry.bounds();
    std::mt19937 rng(13);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::normal_distribution<float> gaussian;
    std::vector<Ray> rays;
    for (int i = 0; i < 4000; ++i) {
        const Vec3f origin = bounds.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * bounds.extent();
        Vec3f direction(gaussian(rng), gaussian(rng), gaussian(rng));
        if (i % 5 == 0) direction[i % 3] = 0.0f;
        // Some start past tnear or end at a finite tfar inside the grid.
        const float tnear = i % 3 == 0 ? unit(rng) : 0.0f;
        const float tfar = i % 7 == 0 ? tnear + unit(rng) : kInfinity;
        rays.push_back({origin, direction, tnear, tfar});
    }
    // Starting exactly on the box faces, into the box, out of it and along the face.
    for (int i = 0; i < 1000; ++i) {
        Vec3f origin = bounds.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * bounds.extent();
        const int axis = i % 3;
        origin[axis] = i % 2 ? bounds.lo[axis] : bounds.hi[axis];
        Vec3f direction(gaussian(rng), gaussian(rng), gaussian(rng));
        if (i % 4 == 0) direction[axis] = 0.0f;
        rays.push_back({origin, direction, 0.0f, kInfinity});
    }
    for (float density : {0.5f, 1.0f, 3.0f})
        EXPECT_GT(expect_agreement_with_brute(geometry, rays, "inside", density), rays.size() / 4);
}

TEST(Grid, OneTriangleMakesAOneCellGrid) {
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0.5f}}};
    GridAccel grid;
    grid.build({triangles, {}}, {});
    ASSERT_EQ(grid.resolution(), (std::array<int, 3>{1, 1, 1}));
    ASSERT_EQ(grid.cell_primitives(0, 0, 0).size(), 1u);
    const std::vector<Ray> rays = {{{0.2f, 0.2f, 5.0f}, {0, 0, -1}, 0.0f, kInfinity},   // from above
                                   {{0.2f, 0.2f, -5.0f}, {0, 0, 1}, 0.0f, kInfinity},   // from below
                                   {{0.2f, 0.2f, 0.15f}, {0, 0, -1}, 0.0f, kInfinity},  // from inside the box
                                   {{2.0f, 2.0f, 5.0f}, {0, 0, -1}, 0.0f, kInfinity}};  // beside
    std::vector<Hit> hits(rays.size());
    TraversalCounters counters;
    grid.intersect(rays, hits, &counters);
    EXPECT_EQ(hits[0].prim, 0);
    EXPECT_EQ(hits[1].prim, 0);
    EXPECT_EQ(hits[2].prim, 0);
    EXPECT_FALSE(hits[3].hit());
    EXPECT_EQ(counters.nodes_visited, 3u);  // the ray beside misses the box
    EXPECT_EQ(grid.stats().count("cells"), 1u);
    EXPECT_EQ(expect_agreement_with_brute({triangles, {}}, rays, "one triangle"), 6u);
}

TEST(Grid, EmptySceneMissesEverything) {
    GridAccel grid;
    grid.build({}, {});
    EXPECT_EQ(grid.stats().count("cells"), 0u);
    EXPECT_EQ(grid.memory_bytes(), 0u);
    const Ray ray{{0, 0, 5}, {0, 0, -1}, 0.0f, kInfinity};
    Hit hit;
    std::uint8_t occluded = 1;
    grid.intersect({&ray, 1}, {&hit, 1});
    grid.occluded({&ray, 1}, {&occluded, 1});
    EXPECT_FALSE(hit.hit());
    EXPECT_EQ(occluded, 0);
}

}  // namespace
}  // namespace lancer
