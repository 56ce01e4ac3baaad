// Every registered structure as an instanced scene's object, against brute force's objects: on a random
// scene of instances, and on objects outside the ordinary size range, which their structures hold scaled.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <string_view>
#include <vector>

#include "instanced_fixture.hpp"
#include "lancer/accel.hpp"
#include "lancer/instances.hpp"
#include "support/ray_sets.hpp"

namespace lancer::testing {
namespace {

// The rays whose answers from another object structure disagree with brute force's (`expected`) as the
// structures may alone (oracle_test.cpp): a hit or a miss alike, occlusion exactly when there is a hit, and
// the same hit with t within 1e-5 and barycentrics within 1e-4, or a tie at the same t.
std::size_t disagreements(const std::vector<InstanceHit>& expected, const std::vector<InstanceHit>& hits,
                          const std::vector<std::uint8_t>& occluded) {
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < expected.size(); ++i) {
        const InstanceHit &a = expected[i], &b = hits[i];
        bool same = a.hit() == b.hit() && (occluded[i] != 0) == a.hit();
        if (same && a.hit()) {
            const bool same_triangle = a.instance == b.instance && a.prim == b.prim;
            same =
                std::fabs(a.t - b.t) <= 1e-5f * std::fabs(a.t) &&
                (same_triangle ? std::fabs(a.u - b.u) <= 1e-4f && std::fabs(a.v - b.v) <= 1e-4f : a.t == b.t);
        }
        mismatches += same ? 0 : 1;
    }
    return mismatches;
}

// Any registered structure can serve as an object (Embree's aside: its own triangle test): each one's
// instanced scene answers as the one over brute force, as the structures agree alone (oracle_test.cpp:
// the same hit, t within 1e-5 and barycentrics within 1e-4, or a tie at the same t).
TEST(InstancedScene, EveryStructureServesAsAnObject) {
    const Fixture fixture = random_fixture(31, 12);
    const InstancedScene reference = make_scene(fixture, "brute", TriangleTest::Watertight);
    std::vector<Ray> rays = testing::random_rays(reference.bounds(), 3000, 32).rays;
    const std::vector<Ray> axis = testing::axis_parallel_rays(reference.bounds(), 500, 33).rays;
    rays.insert(rays.end(), axis.begin(), axis.end());
    std::vector<InstanceHit> expected(rays.size());
    reference.intersect(rays, expected);
    std::size_t structures = 0;
    for (const std::string_view name : accel_names()) {
        if (name == "brute" || name.starts_with("embree")) continue;
        ++structures;
        const InstancedScene scene = make_scene(fixture, name, TriangleTest::Watertight);
        std::vector<InstanceHit> hits(rays.size());
        scene.intersect(rays, hits);
        std::vector<std::uint8_t> occluded(rays.size());
        scene.occluded(rays, occluded);
        EXPECT_EQ(disagreements(expected, hits, occluded), 0u) << name;
        EXPECT_GT(std::ranges::count_if(expected, &InstanceHit::hit), std::ssize(rays) / 10) << name;
    }
    EXPECT_GE(structures, 10u);
}

// An object whose scene lies outside the ordinary size range [2^-20, 2^20] is held by its structure at a
// power-of-two scale (Accel::built_geometry), which a packet structure's single-ray structure sees at scale
// 1: tracing that one with unscaled rays, the instances of bvh8_packet and the other packet structures missed
// what brute force's hit (fuzz finding 31, docs/robustness.md: instances_fuzz's object, transform and ray,
// first here). Each structure's instances answer as brute force's, a huge object's and a tiny one's.
TEST(InstancedScene, ObjectsOutsideTheOrdinarySizeRangeAnswerAsBruteForce) {
    struct Case {
        const char* name;
        std::vector<Vec3f> positions;
        Transform placement;
        std::vector<Ray> rays;
    };
    std::vector<Case> cases(2);
    cases[0].name = "a triangle reaching 1.5e10";
    cases[0].positions = {{0.0f, 0.0f, 0.0f},           {1.0f, 0.0f, 0.0f},        {1.0f, 1.0f, 0.0f},
                          {0.0f, 0x1.c0c0ap+33f, 0.0f}, {1.0f, 0.0f, -0x1.38p+2f}, {-0x1.4p+2f, 0.0f, 0.0f}};
    const float rotation[3][4] = {{0x1.c9f338p-5f, 0x1.fe7afcp-1f, -0x1.b1a3p-5f, -0x1.4p+2f},
                                  {-0x1.b1a3p-5f, 0x1.c9f338p-5f, 0x1.fe7afcp-1f, 0.0f},
                                  {0x1.fe7afcp-1f, -0x1.b1a3p-5f, 0x1.c9f338p-5f, 0.0f}};
    std::copy(&rotation[0][0], &rotation[0][0] + 12, &cases[0].placement.m[0][0]);
    cases[0].rays = {{{-0x1.ap+3f, -0x1p+1f, 1.0f}, {0x1.ap+3f, 0x1.8p+1f, -0x1p-1f}, 0.0f, 0x1.fff2e4p-1f}};
    // A quad 2^-24 wide, placed 2^20 times larger, and rays through it on a grid.
    const float side = 0x1p-24f;
    cases[1].name = "a quad 2^-24 wide";
    cases[1].positions = {{0.0f, 0.0f, 0.0f}, {side, 0.0f, 0.0f}, {side, side, 0.0f},
                          {0.0f, 0.0f, 0.0f}, {side, side, 0.0f}, {0.0f, side, 0.0f}};
    cases[1].placement = Transform::translation({1.0f, 0.0f, 0.0f}) * Transform::scaling(Vec3f(0x1p20f));
    for (int k = 0; k < 64; ++k) {
        const Vec3f aim(1.0f + 0x1p-4f * (float(k % 8) + 0.5f) / 8.0f, 0x1p-4f * (float(k / 8) + 0.5f) / 8.0f,
                        0.0f);
        cases[1].rays.push_back(
            {aim + Vec3f(0.01f, 0.02f, 1.0f), Vec3f(-0.01f, -0.02f, -1.0f), 0.0f, kInfinity});
    }
    for (const Case& c : cases) {
        TriangleMesh mesh;
        mesh.positions = c.positions;
        for (std::uint32_t i = 0; i < c.positions.size(); ++i)
            mesh.indices.push_back(i);
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            const auto make = [&](std::string_view name) {
                InstancedScene scene;
                scene.add_object(mesh, name, build_options(test));
                scene.add_instance(0, c.placement);
                scene.commit();
                return scene;
            };
            const InstancedScene reference = make("brute");
            std::vector<InstanceHit> expected(c.rays.size());
            reference.intersect(c.rays, expected);
            EXPECT_EQ(std::ranges::count_if(expected, &InstanceHit::hit), std::ssize(c.rays)) << c.name;
            for (const std::string_view name : accel_names()) {
                if (name == "brute" || name.starts_with("embree")) continue;
                const InstancedScene scene = make(name);
                std::vector<InstanceHit> hits(c.rays.size());
                scene.intersect(c.rays, hits);
                std::vector<std::uint8_t> occluded(c.rays.size());
                scene.occluded(c.rays, occluded);
                EXPECT_EQ(disagreements(expected, hits, occluded), 0u)
                    << c.name << ", " << name << ", "
                    << (test == TriangleTest::Watertight ? "watertight" : "moller");
            }
        }
    }
}

}  // namespace
}  // namespace lancer::testing
