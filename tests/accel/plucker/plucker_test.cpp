// The Plücker octree: the invariants of its build (2:1 balance, references wherever a primitive overlaps,
// neighbour links symmetric and pointing at the cells across each face and sub-face, the cube map and the
// point location pointing at the cells that hold their points), the walk's leaf order against slab tests,
// and every variant of section 6 against brute force on adversarial scenes and rays.
#include "accel/plucker/plucker.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <span>
#include <tuple>

#include "accel/brute.hpp"
#include "accel/build_util.hpp"
#include "accel/plucker/balance.hpp"
#include "accel/plucker/build.hpp"
#include "accel/plucker/conventions.hpp"
#include "accel/plucker/walk.hpp"
#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "support/brute_force_agreement.hpp"
#include "support/cell_plane_rays.hpp"
#include "support/crossed_leaves.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using plucker::PluckerLayout;

using testing::TestScene;

std::vector<TestScene> make_scenes() {
    std::vector<TestScene> scenes;
    std::mt19937 rng(17);
    scenes.push_back(testing::icosphere_knot_and_spheres(rng, {0.2f, -0.1f, 0.3f}, 200, 8, 20));

    TestScene soup{"triangle soup", {}, {}};
    testing::append_triangle_soup(rng, 1500, 10.0f, 10, 3.0f, 0.3f, soup.triangles);
    scenes.push_back(std::move(soup));
    // Leaves of very different levels side by side: the case the 2:1 rule is about.
    scenes.push_back(testing::huge_triangle_next_to_tiny_ones(rng, 1e3f, 800));
    scenes.push_back({"triangles in one plane", testing::planar_grid_triangles(24), {}});
    return scenes;
}

const std::vector<TestScene>& scenes() {
    static const std::vector<TestScene> all = make_scenes();
    return all;
}

BuildOptions plucker_options(int max_depth, int leaf_size, bool balanced = true, bool stored_boxes = true,
                             bool morton = false, TriangleTest test = TriangleTest::MollerTrumbore) {
    BuildOptions options = build_options(test);
    options.group<PluckerOptions>().max_depth = max_depth;
    options.group<PluckerOptions>().leaf_size = leaf_size;
    options.group<PluckerOptions>().balanced = balanced;
    options.group<PluckerOptions>().stored_boxes = stored_boxes;
    options.group<PluckerOptions>().morton = morton;
    return options;
}

// The leaves of a layout: tree cell, address of its record, and box.
struct Leaf {
    std::uint32_t cell;
    std::uint32_t address;
    OctreeCell geometry;
};

std::map<std::uint32_t, Leaf> leaves_by_address(const PluckerLayout& layout, const Octree& octree) {
    std::map<std::uint32_t, Leaf> leaves;
    for (std::uint32_t i = 0; i < octree.cells.size(); ++i) {
        if (octree.cells[i].is_leaf())
            leaves[layout.locate[i] >> 1] = {i, layout.locate[i] >> 1, octree.cells[i]};
    }
    return leaves;
}

// ---------------------------------------------------------------------------------------------------------
// Build invariants

TEST(PluckerBuild, BalanceKeepsAdjacentLeavesWithinOneLevel) {
    int unbalanced_before = 0;
    for (const TestScene& scene : scenes()) {
        OctreeOptions options;
        options.max_depth = 7;
        options.leaf_size = 2;
        Octree octree = build_octree(scene.geometry(), options);
        const std::size_t leaves_before = std::count_if(octree.cells.begin(), octree.cells.end(),
                                                        [](const OctreeCell& c) { return c.is_leaf(); });
        unbalanced_before += plucker::is_balanced(octree) ? 0 : 1;
        plucker::balance_octree(scene.geometry(), octree);
        EXPECT_TRUE(plucker::is_balanced(octree)) << scene.name;
        const std::size_t leaves_after = std::count_if(octree.cells.begin(), octree.cells.end(),
                                                       [](const OctreeCell& c) { return c.is_leaf(); });
        EXPECT_GE(leaves_after, leaves_before) << scene.name;
        for (const OctreeCell& cell : octree.cells)
            ASSERT_LE(cell.level, 7);
        // Every primitive is referenced in every leaf it overlaps, the balance's new leaves included.
        // primitive_overlaps_box grows the box by grown_for_overlap's relative 1e-6 and rounds a few ulps: a
        // primitive whose bounds miss the box grown twice by it cannot overlap, and is skipped unexamined
        // (a box test instead of the exact one for most of the leaves x primitives pairs).
        const Geometry geometry = scene.geometry();
        std::vector<Box3f> prim_bounds(geometry.size());
        for (std::uint32_t prim = 0; prim < geometry.size(); ++prim)
            prim_bounds[prim] = primitive_bounds(geometry, prim);
        for (const OctreeCell& leaf : octree.cells) {
            if (!leaf.is_leaf()) continue;
            const auto begin = octree.references.begin() + leaf.ref_begin;
            const auto end = octree.references.begin() + leaf.ref_end;
            ASSERT_TRUE(std::is_sorted(begin, end));
            const Box3f box = octree.reference_box(octree.cell_box(leaf));
            const Box3f candidate_box = grown_for_overlap(grown_for_overlap(box));
            for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
                if (intersection(prim_bounds[prim], candidate_box).empty()) continue;
                if (primitive_overlaps_box(geometry, prim, box)) {
                    ASSERT_TRUE(std::binary_search(begin, end, prim)) << scene.name << ": primitive " << prim;
                }
            }
        }
    }
    EXPECT_GE(unbalanced_before, 2);  // the scenes do need the balance
}

// Links (Portalez & Duguet 2016, section 2.2, Figure 2): across each face of a leaf, nothing on the root's
// boundary, else one leaf of the same level or one coarser that contains the face, or the four leaves one
// level finer that tile it, in sub-face order; and the relation is symmetric.
TEST(PluckerBuild, NeighbourLinksAreSymmetricAndPointAtTheCellsAcrossEachSubFace) {
    for (const TestScene& scene : scenes()) {
        for (const bool stored_boxes : {true, false}) {
            PluckerAccel accel;
            accel.build(scene.geometry(), plucker_options(7, 2, true, stored_boxes));
            const PluckerLayout& layout = accel.layout();
            const Octree octree = plucker::recover_octree(layout);
            const auto leaves = leaves_by_address(layout, octree);
            const std::uint32_t header = plucker::header_words(stored_boxes);
            std::size_t four = 0;
            for (const auto& [address, leaf] : leaves) {
                const OctreeCell& cell = leaf.geometry;
                const std::uint32_t* record = layout.cells.data() + address;
                if (stored_boxes) {
                    const plucker::PluckerBox& box = layout.boxes[record[plucker::kBoxWord]];
                    const Box3f expected = octree.cell_box(cell);
                    // A face on the root's boundary is the root's face grown by the tolerance.
                    const auto exit_plane = [&](int axis, float plane) {
                        if (plane == octree.cube.plane(axis, 0, 0)) return plane - layout.tolerance;
                        if (plane == octree.cube.plane(axis, 0, 1)) return plane + layout.tolerance;
                        return plane;
                    };
                    for (int axis = 0; axis < 3; ++axis) {
                        ASSERT_EQ(box.lo(axis), exit_plane(axis, expected.lo[axis]));
                        ASSERT_EQ(box.hi(axis), exit_plane(axis, expected.hi[axis]));
                        ASSERT_EQ(box.mid(axis),
                                  octree.cube.plane(axis, cell.level + 1, 2 * cell.coordinate(axis) + 1));
                    }
                }
                for (int face = 0; face < 6; ++face) {
                    const int axis = plucker::face_axis(face), side = plucker::face_side(face);
                    const std::uint32_t start = plucker::neighbour_start(record[header - 1], face);
                    const std::uint32_t count = plucker::neighbour_end(record[header - 1], face) - start;
                    const std::uint32_t c = cell.coordinate(axis);
                    const bool on_boundary = side ? c == (1u << cell.level) - 1u : c == 0u;
                    ASSERT_EQ(count == 0, on_boundary);
                    ASSERT_TRUE(count == 0 || count == 1 || count == 4);
                    four += count == 4 ? 1 : 0;
                    for (std::uint32_t q = 0; q < count; ++q) {
                        const std::uint32_t link = record[header + start + q];
                        ASSERT_EQ(link & plucker::kInnerBit, 0u);
                        ASSERT_TRUE(leaves.count(link)) << "a link names no leaf record";
                        const OctreeCell& other = leaves.at(link).geometry;
                        // Compare at the finer of the two levels.
                        const int fine = std::max(cell.level, other.level);
                        auto lo = [&](const OctreeCell& x, int a) {
                            return x.coordinate(a) << (fine - x.level);
                        };
                        auto hi = [&](const OctreeCell& x, int a) {
                            return (x.coordinate(a) + 1) << (fine - x.level);
                        };
                        ASSERT_EQ(side ? lo(other, axis) : hi(other, axis),
                                  side ? hi(cell, axis) : lo(cell, axis));
                        for (const int in_face :
                             {plucker::lower_in_face_axis(axis), plucker::upper_in_face_axis(axis)}) {
                            if (count == 1) {
                                ASSERT_LE(other.level, cell.level);
                                ASSERT_GE(other.level + 1, cell.level);
                                ASSERT_LE(lo(other, in_face), lo(cell, in_face));
                                ASSERT_GE(hi(other, in_face), hi(cell, in_face));
                            } else {
                                ASSERT_EQ(other.level, cell.level + 1);
                                const std::uint32_t bit =
                                    in_face == plucker::lower_in_face_axis(axis) ? q & 1u : q >> 1;
                                ASSERT_EQ(other.coordinate(in_face), 2 * cell.coordinate(in_face) + bit);
                            }
                        }
                        // Symmetry: this leaf is among the other's neighbours across the opposite face.
                        const std::uint32_t* back = layout.cells.data() + link;
                        const int opposite = plucker::make_face(axis, 1 - side);
                        const std::uint32_t back_start = plucker::neighbour_start(back[header - 1], opposite);
                        const std::uint32_t back_end = plucker::neighbour_end(back[header - 1], opposite);
                        ASSERT_TRUE(std::find(back + header + back_start, back + header + back_end,
                                              address) != back + header + back_end);
                    }
                }
            }
            EXPECT_GT(four, 10u) << scene.name;
        }
    }
}

// The cube map covers the faces of the geometry's bounds (walk.hpp's entry_leaf).
TEST(PluckerBuild, TheCubeMapAndThePointLocationFindTheCellsHoldingTheirPoints) {
    for (const TestScene& scene : scenes()) {
        PluckerAccel accel;
        accel.build(scene.geometry(), plucker_options(7, 2));
        const PluckerLayout& layout = accel.layout();
        const Octree octree = plucker::recover_octree(layout);
        const auto leaves = leaves_by_address(layout, octree);
        for (int face = 0; face < 6; ++face) {
            const int axis = plucker::face_axis(face);
            const std::uint32_t level = layout.cube_map.level[static_cast<std::size_t>(face)];
            const std::uint32_t size = 1u << level;
            // The face's layer: the cells of `level` that hold the bounds' face, ties to the side of the rays
            // entering through it.
            const bool upper = plucker::face_side(face) != 0;
            const float plane = upper ? layout.bounds.hi[axis] : layout.bounds.lo[axis];
            const std::uint32_t layer = plucker::cell_index(layout.cube, axis, level, plane, upper ? 0u : 1u);
            const float below = octree.cube.plane(axis, static_cast<int>(level), layer),
                        above = octree.cube.plane(axis, static_cast<int>(level), layer + 1);
            ASSERT_TRUE(layer == 0 || (upper ? below < plane : below <= plane)) << "face " << face;
            ASSERT_TRUE(layer == size - 1 || (upper ? plane <= above : plane < above)) << "face " << face;
            for (std::uint32_t j = 0; j < size; ++j) {
                for (std::uint32_t i = 0; i < size; ++i) {
                    const std::uint32_t texel =
                        layout.cube_map.texels[layout.cube_map.offset[static_cast<std::size_t>(face)] + i +
                                               (j << level)];
                    // The texel's centre, at level + 1, in the face's layer.
                    std::array<std::uint32_t, 3> centre{};
                    centre[static_cast<std::size_t>(axis)] = 2u * layer + 1u;
                    centre[static_cast<std::size_t>(plucker::lower_in_face_axis(axis))] = 2 * i + 1;
                    centre[static_cast<std::size_t>(plucker::upper_in_face_axis(axis))] = 2 * j + 1;
                    const std::uint32_t cell = plucker::find_cell(octree, static_cast<int>(level) + 1,
                                                                  centre[0], centre[1], centre[2]);
                    if (texel & plucker::kInnerBit) {
                        // A texel over deeper leaves names the inner cell of its level that holds it.
                        ASSERT_EQ(octree.cells[texel & plucker::kAddressMask].level, level);
                        ASSERT_EQ(plucker::find_cell(octree, static_cast<int>(level), centre[0] >> 1,
                                                     centre[1] >> 1, centre[2] >> 1),
                                  texel & plucker::kAddressMask);
                    } else {
                        ASSERT_TRUE(leaves.count(texel));
                        ASSERT_EQ(leaves.at(texel).cell, cell)
                            << "face " << face << " texel " << i << ", " << j;
                    }
                }
            }
        }
        // Point location: random points, found leaf contains them.
        std::mt19937 rng(9);
        std::uniform_real_distribution<float> unit(0.0f, 1.0f);
        const Box3f root = octree.cell_box(octree.cells[0]);
        for (int n = 0; n < 2000; ++n) {
            const Vec3f p = root.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * root.extent().x;
            const plucker::WalkRay ray({p, {1, 1, 1}, 0.0f, kInfinity}, layout.cube, plucker::kTables);
            const std::uint32_t address = plucker::descend(plucker::view_of(layout), 0, 0, {0, 0, 0}, p, ray);
            ASSERT_TRUE(leaves.count(address));
            ASSERT_TRUE(octree.cell_box(leaves.at(address).geometry).contains(p));
        }
    }
}

TEST(PluckerBuild, IsDeterministicAndFollowsTheAutomaticDepth) {
    EXPECT_EQ(PluckerAccel::automatic_depth(69451), 8);    // the bunny of section 5.2
    EXPECT_EQ(PluckerAccel::automatic_depth(345944), 10);  // the armadillo
    EXPECT_EQ(PluckerAccel::automatic_depth(871414), 11);  // the dragon
    EXPECT_EQ(PluckerAccel::automatic_depth(0), 2);
    const TestScene& scene = scenes()[0];
    PluckerAccel a, b;
    a.build(scene.geometry(), {});
    b.build(scene.geometry(), {});
    EXPECT_EQ(a.stats().value("max_depth"), PluckerAccel::automatic_depth(scene.geometry().size()));
    EXPECT_EQ(a.layout().cells, b.layout().cells);
    EXPECT_EQ(a.layout().locate, b.layout().locate);
    EXPECT_EQ(a.layout().cube_map.texels, b.layout().cube_map.texels);
}

// Table 1 of the seed: the 2:1 rule costs leaves (120-133% on the Stanford meshes); stats count them.
TEST(PluckerBuild, TheUnconstrainedOctreeHasFewerLeavesAndTheSameStatistics) {
    const TestScene& scene = scenes()[2];
    PluckerAccel balanced, unconstrained;
    balanced.build(scene.geometry(), plucker_options(8, 2, true));
    unconstrained.build(scene.geometry(), plucker_options(8, 2, false));
    EXPECT_GT(balanced.stats().count("leaves"), unconstrained.stats().count("leaves"));
    const Octree octree = plucker::recover_octree(balanced.layout());
    const auto leaf_count = static_cast<std::size_t>(std::count_if(
        octree.cells.begin(), octree.cells.end(), [](const OctreeCell& c) { return c.is_leaf(); }));
    EXPECT_EQ(balanced.stats().count("leaves"), leaf_count);
    EXPECT_EQ(balanced.stats().count("nodes"), octree.cells.size());
    EXPECT_EQ(balanced.stats().count("references"), balanced.layout().primitives.size());
    EXPECT_EQ(balanced.memory_bytes(),
              balanced.layout().cells.size() * 4 + balanced.layout().primitives.size() * 40 +
                  balanced.layout().boxes.size() * 36 + balanced.layout().cube_map.texels.size() * 4 +
                  balanced.layout().locate.size() * 4);
}

// ---------------------------------------------------------------------------------------------------------
// The walk

// The slab interval of a box along the ray.
std::pair<float, float> slab_interval(const Box3f& box, const Ray& ray) {
    float entry = -kInfinity, exit = kInfinity;
    for (int axis = 0; axis < 3; ++axis) {
        if (ray.direction[axis] == 0.0f) {
            if (ray.origin[axis] < box.lo[axis] || ray.origin[axis] > box.hi[axis]) entry = kInfinity;
            continue;
        }
        const float a = (box.lo[axis] - ray.origin[axis]) / ray.direction[axis],
                    b = (box.hi[axis] - ray.origin[axis]) / ray.direction[axis];
        entry = std::max(entry, std::min(a, b));
        exit = std::min(exit, std::max(a, b));
    }
    return {entry, exit};
}

// A leaf's box and that box grown by the scene's tolerance, computed once per structure rather than per ray.
struct LeafBoxes {
    std::uint32_t address;
    Box3f box, grown;
};

std::vector<LeafBoxes> leaf_boxes(const std::map<std::uint32_t, Leaf>& leaves, const Octree& octree) {
    std::vector<LeafBoxes> boxes;
    boxes.reserve(leaves.size());
    for (const auto& [address, leaf] : leaves) {
        const Box3f box = octree.cell_box(leaf.geometry);
        boxes.push_back({address, box, octree.reference_box(box)});
    }
    return boxes;
}

// The leaves whose slab interval meets [tnear, tfar] within `walked` (the layout's bounds, where the walk
// goes) with positive length, ordered by entry; `touched`: the leaves whose box grown by the scene's
// tolerance the ray meets at all (docs/numerical-contract.md).
std::vector<std::uint32_t> leaves_by_slabs(std::span<const LeafBoxes> leaves, const Ray& ray,
                                           const Box3f& walked, std::vector<std::uint32_t>& touched) {
    std::vector<std::tuple<float, float, std::uint32_t>> crossed;
    touched.clear();
    const auto [walked_entry, walked_exit] = slab_interval(walked, ray);
    const float from = std::max(ray.tnear, walked_entry), to = std::min(ray.tfar, walked_exit);
    for (const LeafBoxes& leaf : leaves) {
        const auto [grown_entry, grown_exit] = slab_interval(leaf.grown, ray);
        const float grown_slack = 1e-5f * (std::fabs(grown_entry) + std::fabs(grown_exit) + 1.0f);
        // A leaf whose grown box the ray misses is not crossed either (the box lies inside it).
        if (!(grown_entry <= grown_exit + grown_slack && grown_entry <= ray.tfar + grown_slack &&
              grown_exit + grown_slack >= ray.tnear))
            continue;
        touched.push_back(leaf.address);
        const auto [entry, exit] = slab_interval(leaf.box, ray);
        const float slack = 1e-5f * (std::fabs(entry) + std::fabs(exit) + 1.0f);
        if (entry + slack < exit && from + slack < to && entry + slack < to && exit > from + slack)
            crossed.emplace_back(entry, exit, leaf.address);
    }
    return testing::in_order_of_entry(std::move(crossed));
}

TEST(PluckerWalk, VisitsTheLeavesTheRayCrossesInOrder) {
    std::size_t compared = 0, longest = 0;
    for (const TestScene& scene : scenes()) {
        for (const BuildOptions& options : {plucker_options(7, 2), plucker_options(5, 1, true, false, true),
                                            plucker_options(7, 2, false)}) {
            PluckerAccel accel;
            accel.build(scene.geometry(), options);
            const Octree octree = plucker::recover_octree(accel.layout());
            const std::vector<LeafBoxes> leaves =
                leaf_boxes(leaves_by_address(accel.layout(), octree), octree);
            const Box3f bounds = scene.geometry().bounds();
            constexpr std::size_t share = testing::kSanitizedShare;
            std::vector<Ray> rays = testing::random_rays(bounds, 400 / share, 21).rays;
            for (const auto& extra : {testing::axis_parallel_rays(bounds, 200 / share, 22),
                                      testing::clipped_rays(bounds, 200 / share, 23)})
                rays.insert(rays.end(), extra.rays.begin(), extra.rays.end());
            std::vector<std::uint32_t> touched;
            for (std::size_t i = 0; i < rays.size(); ++i) {
                const std::vector<std::uint32_t> crossed =
                    leaves_by_slabs(leaves, rays[i], accel.layout().bounds, touched);
                const std::vector<std::uint32_t> visited = accel.leaves_along(rays[i]);
                // Every leaf crossed is visited, in the order of entry; a leaf visited beyond them is one the
                // ray touches at an edge or corner.
                std::size_t next = 0;
                for (const std::uint32_t leaf : visited) {
                    ASSERT_TRUE(std::find(touched.begin(), touched.end(), leaf) != touched.end())
                        << scene.name << " ray " << i << ": visits a leaf the ray does not touch";
                    if (next < crossed.size() && leaf == crossed[next]) ++next;
                }
                ASSERT_EQ(next, crossed.size()) << scene.name << " ray " << i << ": skips a crossed leaf";
                ++compared;
                longest = std::max(longest, visited.size());
            }
        }
    }
    EXPECT_GT(longest, 20u);
    EXPECT_GT(compared, 8000u / testing::kSanitizedShare);
}

// Rays lying in cell planes (zero components, origins exactly on the planes of every level, along faces and
// edges): every point of the ray inside the root and the geometry's bounds lies in a visited leaf, and
// answers agree with brute force.
TEST(PluckerWalk, RaysInCellPlanesAndAlongEdges) {
    const TestScene& scene = scenes()[0];
    const Geometry geometry = scene.geometry();
    for (const bool balanced : {true, false}) {
        const BuildOptions options = plucker_options(6, 2, balanced);
        PluckerAccel accel;
        accel.build(geometry, options);
        const Octree octree = plucker::recover_octree(accel.layout());
        const auto leaves = leaves_by_address(accel.layout(), octree);
        const std::vector<Ray> rays = testing::cell_plane_rays(octree, 3000, 3);
        const Box3f root = octree.cell_box(octree.cells[0]);
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            BuildOptions with_test = options;
            with_test.triangle_test = test;
            PluckerAccel tested;
            tested.build(geometry, with_test);
            testing::expect_brute_force_answers(tested, geometry, test, rays, 200);
        }
        for (std::size_t i = 0; i < rays.size(); ++i) {
            const std::vector<std::uint32_t> visited = accel.leaves_along(rays[i]);
            for (float t = 0.0f; t < 3.0f * root.extent().x; t += 0.02f * root.extent().x) {
                const Vec3f p = rays[i].origin + t * rays[i].direction;
                if (!root.contains(p) || !accel.layout().bounds.contains(p)) continue;
                ASSERT_TRUE(std::any_of(visited.begin(), visited.end(),
                                        [&](std::uint32_t leaf) {
                                            return octree.cell_box(leaves.at(leaf).geometry).contains(p);
                                        }))
                    << "ray " << i << " point at t = " << t << " is in no visited leaf";
            }
        }
    }
}

// The seed returns at the first leaf with a hit (section 4.2.3). A: a slanted triangle referenced by the
// first leaf but hit far beyond that leaf's exit; B: a small triangle across the ray in a later leaf, closer.
TEST(PluckerWalk, AHitBeyondTheLeafExitDoesNotEndTheWalk) {
    const testing::HitBeyondLeafExit example;
    const TestScene& scene = example.scene;
    const Ray& ray = example.ray;
    PluckerAccel accel;
    accel.build(scene.geometry(), plucker_options(6, 1));
    const std::vector<std::uint32_t> leaves = accel.leaves_along(ray);
    ASSERT_GT(leaves.size(), 2u);
    const std::uint32_t* first = accel.layout().cells.data() + leaves.front();
    ASSERT_EQ(first[plucker::kTriangleCount], 1u);
    ASSERT_EQ(accel.layout().primitives[first[plucker::kTriangleOffset]].prim, 0u);
    std::vector<Hit> hits(1);
    accel.intersect({&ray, 1}, hits);
    EXPECT_EQ(hits[0].prim, 1);
    EXPECT_FLOAT_EQ(hits[0].t, 4.0f);
}

TEST(PluckerWalk, StopsOnceTheClosestHitLiesBeforeTheNextLeaf) {
    const TestScene& scene = scenes()[0];
    PluckerAccel accel;
    accel.build(scene.geometry(), plucker_options(8, 2));
    const Ray ray{{0.2f, -0.1f, -5.0f}, {0.01f, 0.02f, 1.0f}, 0.0f, kInfinity};
    std::vector<Hit> hits(1);
    TraversalCounters counters;
    accel.intersect({&ray, 1}, hits, &counters);
    ASSERT_TRUE(hits[0].hit());
    const std::size_t leaves = accel.leaves_along(ray).size();
    EXPECT_GT(leaves, 10u);
    EXPECT_LT(counters.nodes_visited, leaves / 2);
}

// The root is a cube anchored at the bounds' lower corner; over a flat scene most of it is empty. A ray
// through that empty part and outside the bounds enters no leaf, and one that reaches the bounds from it
// starts at them: straight down onto the plane, its first leaf holds the hit.
TEST(PluckerWalk, WalksOnlyInsideTheGeometrysBounds) {
    const TestScene& scene = scenes()[3];  // triangles in the plane z = 0, over [0, 24]^2
    for (const bool balanced : {true, false}) {
        PluckerAccel accel;
        accel.build(scene.geometry(), plucker_options(7, 2, balanced));
        ASSERT_GT(accel.layout().cube.size, 20.0f);
        const std::vector<Ray> rays = {{{-1.0f, 3.3f, 5.0f}, {1.0f, 0.1f, 0.0f}, 0.0f, kInfinity},
                                       {{7.3f, 5.1f, 23.0f}, {0.0f, 0.0f, -1.0f}, 0.0f, kInfinity}};
        std::vector<Hit> hits(rays.size());
        for (std::size_t i = 0; i < rays.size(); ++i) {
            TraversalCounters counters;
            accel.intersect({&rays[i], 1}, {&hits[i], 1}, &counters);
            EXPECT_EQ(counters.nodes_visited, i) << "ray " << i;
        }
        EXPECT_FALSE(hits[0].hit());
        ASSERT_TRUE(hits[1].hit());
        EXPECT_EQ(hits[1].t, 23.0f);
    }
}

// ---------------------------------------------------------------------------------------------------------
// Every variant against brute force (the registry's default is checked by oracle_test.cpp).

class PluckerVariant : public ::testing::TestWithParam<std::tuple<bool, bool, bool>> {};

TEST_P(PluckerVariant, AgreesWithBruteForce) {
    const auto [balanced, stored_boxes, morton] = GetParam();
    static testing::BruteForceCache brute_force;  // shared by the variants, run in one process
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        for (std::size_t scene_index = 0; scene_index < scenes().size(); ++scene_index) {
            const TestScene& scene = scenes()[scene_index];
            const Geometry geometry = scene.geometry();
            const Box3f bounds = geometry.bounds();
            constexpr std::size_t share = testing::kSanitizedShare;
            const std::vector<testing::RaySet> sets = {
                testing::random_rays(bounds, 2000 / share, 41),
                testing::vertex_and_edge_rays(scene.triangles, 1500 / share, 42),
                testing::axis_parallel_rays(bounds, 1500 / share, 43),
                testing::clipped_rays(bounds, 1000 / share, 44), testing::hostile_rays(bounds)};
            for (const int max_depth : {0, 9}) {
                PluckerAccel accel;
                accel.build(geometry, plucker_options(max_depth, 3, balanced, stored_boxes, morton, test));
                for (std::size_t set_index = 0; set_index < sets.size(); ++set_index) {
                    const testing::RaySet& set = sets[set_index];
                    const std::vector<Hit>& expected =
                        brute_force.hits(scene_index, set_index, test, geometry, set.rays);
                    std::vector<Hit> hits(set.rays.size());
                    std::vector<std::uint8_t> occluded(set.rays.size());
                    accel.intersect(set.rays, hits);
                    accel.occluded(set.rays, occluded);
                    const Agreement closest = compare_hits(set.rays, expected, hits);
                    EXPECT_EQ(closest.mismatches, 0u)
                        << scene.name << ", " << set.name << ": " << closest.summary();
                    const Agreement any = compare_occlusion(set.rays, expected, occluded);
                    EXPECT_EQ(any.mismatches, 0u) << scene.name << ", " << set.name << ": " << any.summary();
                }
            }
        }
    }
}

std::string variant_name(const ::testing::TestParamInfo<std::tuple<bool, bool, bool>>& param_info) {
    const auto& [balanced, stored_boxes, morton] = param_info.param;
    return std::string(balanced ? "Balanced" : "Unconstrained") +
           (stored_boxes ? "StoredBoxes" : "ComputedBoxes") + (morton ? "Morton" : "BuildOrder");
}

INSTANTIATE_TEST_SUITE_P(Layouts, PluckerVariant,
                         ::testing::Combine(::testing::Bool(), ::testing::Bool(), ::testing::Bool()),
                         variant_name);

}  // namespace
}  // namespace lancer
