// Every registered structure against the brute-force oracle, on every scene and ray set below, for both
// triangle tests, closest hit and occlusion. A new structure added to the registry is tested here at once.
#include <gtest/gtest.h>

#include <random>
#include <string>

#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "support/configurations.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::knot_triangles;
using testing::TestScene;

std::vector<TestScene> make_scenes() {
    std::vector<TestScene> scenes;
    std::mt19937 rng(2024);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    auto point = [&](float scale) { return Vec3f(unit(rng), unit(rng), unit(rng)) * scale; };

    scenes.push_back(testing::icosphere_knot_and_spheres(rng, {0, 0, 0}, 300, 10, 40));

    TestScene soup{"random triangle soup", {}, {}};
    testing::append_triangle_soup(rng, 3000, 10.0f, 10, 3.0f, 0.3f, soup.triangles);
    scenes.push_back(std::move(soup));

    scenes.push_back({"empty", {}, {}});
    scenes.push_back({"one triangle", {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}}, {}});
    scenes.push_back({"one sphere", {}, {{{0, 0, 0}, 1.0f, 0}}});

    scenes.push_back({"all triangles in one plane", testing::planar_grid_triangles(40), {}});

    // A ray that meets them tests them all, and one through their shared vertices or edges takes the exact
    // predicate for each, so the test's time grows with their count: the sanitized build holds
    // kSanitizedShare times fewer, as it traces fewer rays (docs/log/ci.md has the timings).
    constexpr std::size_t kCoincident = 1000 / testing::kSanitizedShare;
    TestScene coincident{std::to_string(kCoincident) + " coincident triangles", {}, {}};
    coincident.triangles.assign(kCoincident, Triangle{{0, 0, 0}, {1, 0, 0.5f}, {0, 1, 1}});
    coincident.triangles.push_back({{-1, -1, 2}, {2, -1, 2}, {-1, 2, 2}});
    scenes.push_back(std::move(coincident));

    scenes.push_back(testing::huge_triangle_next_to_tiny_ones(rng, 1e4f, 2000));

    TestScene degenerate{"degenerate and duplicate triangles", {}, {}};
    make_icosphere(2, {0, 0, 0}, 1.0f).append_triangles(degenerate.triangles);
    for (int i = 0; i < 200; ++i) {
        const Vec3f a = point(2.0f) - Vec3f(1.0f), b = point(2.0f) - Vec3f(1.0f);
        degenerate.triangles.push_back({a, b, 0.5f * (a + b)});  // zero area, collinear
        degenerate.triangles.push_back({a, a, a});               // a point
        degenerate.triangles.push_back(degenerate.triangles[static_cast<std::size_t>(i)]);  // duplicate
    }
    degenerate.spheres.push_back({{0.3f, 0.3f, 0.3f}, 0.0f, 0});  // zero radius
    scenes.push_back(std::move(degenerate));

    // 1e6 from the origin floats are 1/16 apart: a closed mesh of radius 50 keeps its shape, but cell
    // boundaries, slab tests and barycentrics all work with few bits left below the offset.
    TestScene far{"far from the origin (1e6 offset)", {}, {}};
    const Vec3f offset(1e6f, -1e6f, 1e6f);
    make_icosphere(3, offset, 50.0f).append_triangles(far.triangles);
    for (Triangle triangle : knot_triangles(200)) {
        for (Vec3f* vertex : {&triangle.v0, &triangle.v1, &triangle.v2})
            *vertex = *vertex * 40.0f + offset + Vec3f(120.0f, 0.0f, 0.0f);
        far.triangles.push_back(triangle);
    }
    for (int i = 0; i < 20; ++i)
        far.spheres.push_back({offset + point(200.0f) - Vec3f(100.0f), 2.0f + 10.0f * unit(rng), 0});
    far.spheres.push_back({offset + Vec3f(0.0f, 80.0f, 0.0f), 0.0f, 0});  // zero radius, far away
    scenes.push_back(std::move(far));
    return scenes;
}

const std::vector<TestScene>& scenes() {
    static const std::vector<TestScene> all = make_scenes();
    return all;
}

std::vector<testing::RaySet> ray_sets(const TestScene& scene) {
    Box3f bounds = scene.geometry().bounds();
    if (bounds.empty()) bounds = {{-1, -1, -1}, {1, 1, 1}};
    constexpr std::size_t share = testing::kSanitizedShare;
    return {testing::random_rays(bounds, 4000 / share, 1),
            testing::vertex_and_edge_rays(scene.triangles, 3000 / share, 2),
            testing::axis_parallel_rays(bounds, 3000 / share, 3),
            testing::clipped_rays(bounds, 2000 / share, 4), testing::hostile_rays(bounds)};
}

// The oracle's answers, computed once per scene, ray set and triangle test and shared by all structures.
const std::vector<Hit>& oracle_hits(std::size_t scene_index, std::size_t set_index,
                                    const testing::RaySet& set, TriangleTest test) {
    static testing::BruteForceCache cache;
    return cache.hits(scene_index, set_index, test, scenes()[scene_index].geometry(), set.rays);
}

class OracleTest : public ::testing::TestWithParam<testing::Configuration> {};

TEST_P(OracleTest, AgreesWithBruteForceOnEveryRay) {
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        for (std::size_t scene_index = 0; scene_index < scenes().size(); ++scene_index) {
            const TestScene& scene = scenes()[scene_index];
            const std::unique_ptr<Accel> accel = make_accel(GetParam().name);
            accel->build(scene.geometry(), GetParam().options(test));
            const std::vector<testing::RaySet> sets = ray_sets(scene);
            for (std::size_t set_index = 0; set_index < sets.size(); ++set_index) {
                const testing::RaySet& set = sets[set_index];
                const std::vector<Hit>& expected = oracle_hits(scene_index, set_index, set, test);
                std::vector<Hit> hits(set.rays.size());
                accel->intersect(set.rays, hits);
                const Agreement closest = compare_hits(set.rays, expected, hits);
                EXPECT_EQ(closest.mismatches, 0u)
                    << GetParam().label() << ", " << scene.name << ", " << set.name << ", "
                    << (test == TriangleTest::Watertight ? "watertight" : "moller") << ": "
                    << closest.summary();
                // The packet call (Accel::intersect_packet), partial packets included: the same answers.
                const Agreement packets =
                    compare_hits(set.rays, expected, testing::intersect_in_packets(*accel, set.rays));
                EXPECT_EQ(packets.mismatches, 0u) << GetParam().label() << " in packets, " << scene.name
                                                  << ", " << set.name << ": " << packets.summary();
                std::vector<std::uint8_t> occluded(set.rays.size());
                accel->occluded(set.rays, occluded);
                const Agreement any = compare_occlusion(set.rays, expected, occluded);
                EXPECT_EQ(any.mismatches, 0u)
                    << GetParam().label() << ", " << scene.name << ", " << set.name << ": " << any.summary();
            }
        }
    }
}

TEST_P(OracleTest, CountersSeeEveryValidRay) {
    const TestScene& scene = scenes()[0];
    const std::unique_ptr<Accel> accel = make_accel(GetParam().name);
    accel->build(scene.geometry(), GetParam().options(TriangleTest::MollerTrumbore));
    const testing::RaySet set = testing::random_rays(scene.geometry().bounds(), 1000, 5);
    std::vector<Hit> hits(set.rays.size()), counted_hits(set.rays.size());
    accel->intersect(set.rays, hits);
    TraversalCounters counters;
    accel->intersect(set.rays, counted_hits, &counters);
    EXPECT_EQ(counters.rays, set.rays.size());
    EXPECT_GT(counters.nodes_visited, 0u);
    EXPECT_GT(counters.prims_tested, 0u);
    // Counting must not change an answer.
    for (std::size_t i = 0; i < hits.size(); ++i) {
        ASSERT_EQ(hits[i].prim, counted_hits[i].prim);
        ASSERT_EQ(hits[i].t, counted_hits[i].t);
    }
}

// Every lancer structure, and those built on the binary BVH with spatial splits too. Embree, measured beside
// them, keeps its own triangle test and sphere rounding: it is checked against brute force with its own
// tolerance in embree_test.cpp.
std::vector<testing::Configuration> structures_under_test() {
    std::vector<std::string_view> names = accel_names();
    std::erase(names, std::string_view("brute"));
    std::erase_if(names, [](std::string_view name) { return name.starts_with("embree"); });
    return testing::agreement_configurations(names);
}

INSTANTIATE_TEST_SUITE_P(Structures, OracleTest, ::testing::ValuesIn(structures_under_test()),
                         [](const auto& param_info) { return param_info.param.label(); });
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(OracleTest);

}  // namespace
}  // namespace lancer
