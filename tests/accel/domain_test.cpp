// The coordinate domain of the numerical contract (docs/numerical-contract.md, "Coordinate domain"): a scene
// anywhere in [-2^60, 2^60], however large or small, is answered by every structure, both triangle tests and
// every query as the same scene scaled into the ordinary range is, bit for bit once scaled back: a power of
// two changes no bit of a product that neither overflows nor underflows, so the structure's answers on an
// ordinary scene, which the oracle tests hold to brute force, are the reference. Beyond the domain, every
// build is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "accel/bvh/nearest_point.hpp"
#include "lancer/accel.hpp"
#include "lancer/packet.hpp"
#include "lancer/queries.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::TestScene;

// An ordinary scene: a torus knot, a triangle with corners at +-8 (2^3) under it, and two spheres.
TestScene ordinary_scene() {
    TestScene scene{
        "knot", testing::knot_triangles(24), {{{0.5f, 0.25f, 1.5f}, 0.75f, 0}, {{-2, 1, 0}, 0.5f, 0}}};
    scene.triangles.push_back({{-8, -8, -8}, {8, -8, -8}, {-8, 8, -8}});
    return scene;
}

TestScene scaled_scene(const TestScene& scene, int exponent) {
    TestScene scaled{scene.name + " x 2^" + std::to_string(exponent), {}, {}};
    const auto scale = [&](Vec3f p) {
        return Vec3f(std::ldexp(p.x, exponent), std::ldexp(p.y, exponent), std::ldexp(p.z, exponent));
    };
    for (const Triangle& t : scene.triangles)
        scaled.triangles.push_back({scale(t.v0), scale(t.v1), scale(t.v2)});
    for (const Sphere& s : scene.spheres)
        scaled.spheres.push_back({scale(s.center), std::ldexp(s.radius, exponent), s.material});
    return scaled;
}

// The same line in the scaled scene's units: origin and interval scaled, direction kept.
Ray scaled_ray(const Ray& ray, int exponent) {
    return {{std::ldexp(ray.origin.x, exponent), std::ldexp(ray.origin.y, exponent),
             std::ldexp(ray.origin.z, exponent)},
            ray.direction,
            std::ldexp(ray.tnear, exponent),
            std::ldexp(ray.tfar, exponent)};
}

std::vector<Ray> ordinary_rays(const TestScene& scene) {
    const Box3f bounds = scene.geometry().bounds();
    std::vector<Ray> rays;
    for (const testing::RaySet& set :
         {testing::random_rays(bounds, 1500, 71), testing::vertex_and_edge_rays(scene.triangles, 1000, 72),
          testing::axis_parallel_rays(bounds, 500, 73), testing::clipped_rays(bounds, 500, 74)}) {
        rays.insert(rays.end(), set.rays.begin(), set.rays.end());
    }
    return rays;
}

std::vector<Vec3f> ordinary_points(const TestScene& scene) {
    const std::vector<Ray> rays = testing::random_rays(scene.geometry().bounds(), 400, 75).rays;
    std::vector<Vec3f> points;
    for (const Ray& ray : rays)
        points.push_back(ray.origin);
    return points;
}

// What a structure and the queries over it answer on a scene.
struct Answers {
    std::vector<Hit> closest, packet;
    std::vector<std::uint8_t> occluded;
    std::vector<std::vector<Hit>> all_hits;
    std::vector<NearestPoint> nearest;
};

Answers answers(std::string_view name, TriangleTest test, const Geometry& geometry, std::span<const Ray> rays,
                std::span<const Vec3f> points) {
    const std::unique_ptr<Accel> accel = make_accel(name);
    accel->build(geometry, build_options(test));
    Answers a;
    a.closest.resize(rays.size());
    accel->intersect(rays, a.closest);
    a.occluded.resize(rays.size());
    accel->occluded(rays, a.occluded);
    for (std::size_t first = 0; first < rays.size(); first += RayPacket::kMaxSize) {
        RayPacket packet;
        packet.size = static_cast<int>(std::min<std::size_t>(RayPacket::kMaxSize, rays.size() - first));
        for (int lane = 0; lane < packet.size; ++lane)
            packet.set(lane, rays[first + static_cast<std::size_t>(lane)]);
        HitPacket hits;
        accel->intersect_packet(packet, hits);
        for (int lane = 0; lane < packet.size; ++lane)
            a.packet.push_back(hits.hit(lane));
    }
    const GeometryQueries queries(*accel, geometry, test);
    for (const Ray& ray : rays)
        queries.all_hits(ray, a.all_hits.emplace_back());
    for (const Vec3f& p : points)
        a.nearest.push_back(queries.nearest_point(p));
    return a;
}

// The differences between `got`, on the scene scaled by 2^exponent, and `expected` scaled: t and distances by
// 2^exponent, the rest the same. Each is described in `mismatches` (the first few printed by the caller).
class Comparison {
  public:
    explicit Comparison(int exponent) : exponent_(exponent) {}

    void hit(const Hit& got, const Hit& expected, const std::string& context) {
        const bool same =
            got.prim == expected.prim && (!expected.hit() || (got.t == std::ldexp(expected.t, exponent_) &&
                                                              got.u == expected.u && got.v == expected.v));
        if (!same) {
            add(context + ": prim " + std::to_string(got.prim) + " t " + std::to_string(got.t) +
                ", expected " + std::to_string(expected.prim) + " t " +
                std::to_string(std::ldexp(expected.t, exponent_)));
        }
    }
    void nearest(const NearestPoint& got, const NearestPoint& expected, const std::string& context) {
        const auto scaled = [&](float x) { return std::ldexp(x, exponent_); };
        const bool same =
            got.prim == expected.prim && got.distance == scaled(expected.distance) &&
            got.point.x == scaled(expected.point.x) && got.point.y == scaled(expected.point.y) &&
            got.point.z == scaled(expected.point.z) && got.u == expected.u && got.v == expected.v;
        if (!same) {
            add(context + ": prim " + std::to_string(got.prim) + " distance " + std::to_string(got.distance) +
                ", expected " + std::to_string(expected.prim) + " " +
                std::to_string(scaled(expected.distance)));
        }
    }
    void add(std::string mismatch) { mismatches.push_back(std::move(mismatch)); }

    std::vector<std::string> mismatches;

  private:
    int exponent_;
};

class DomainTest : public ::testing::TestWithParam<std::string_view> {};

// Scenes up to the domain's edge (the big triangle's corners at +-2^60) and down to 2^-90 of the ordinary
// one, whose products of three lengths overflowed (t = inf from 4e12 up) or underflowed in float.
TEST_P(DomainTest, ScaledSceneIsAnsweredAsTheOrdinaryOne) {
    const TestScene ordinary = ordinary_scene();
    const std::vector<Ray> rays = ordinary_rays(ordinary);
    const std::vector<Vec3f> points = ordinary_points(ordinary);
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const Answers expected = answers(GetParam(), test, ordinary.geometry(), rays, points);
        std::size_t hits = 0;
        for (const Hit& hit : expected.closest)
            hits += hit.hit() ? 1 : 0;
        ASSERT_GT(hits, rays.size() / 4);
        for (const int exponent : {57, 44, 41, 24, -24, -60, -90}) {
            const TestScene scene = scaled_scene(ordinary, exponent);
            std::vector<Ray> scaled_rays;
            for (const Ray& ray : rays)
                scaled_rays.push_back(scaled_ray(ray, exponent));
            std::vector<Vec3f> scaled_points;
            for (const Vec3f& p : points)
                scaled_points.push_back(
                    {std::ldexp(p.x, exponent), std::ldexp(p.y, exponent), std::ldexp(p.z, exponent)});
            const Answers got = answers(GetParam(), test, scene.geometry(), scaled_rays, scaled_points);
            const std::string where = scene.name + (test == TriangleTest::Watertight ? " watertight" : " MT");
            Comparison compare(exponent);
            for (std::size_t i = 0; i < rays.size(); ++i) {
                const std::string context = where + " ray " + std::to_string(i);
                compare.hit(got.closest[i], expected.closest[i], context + " closest");
                compare.hit(got.packet[i], expected.packet[i], context + " packet");
                if (got.occluded[i] != expected.occluded[i]) compare.add(context + " occluded");
                if (got.all_hits[i].size() != expected.all_hits[i].size()) {
                    compare.add(context + " all hits: " + std::to_string(got.all_hits[i].size()) +
                                ", expected " + std::to_string(expected.all_hits[i].size()));
                    continue;
                }
                for (std::size_t h = 0; h < got.all_hits[i].size(); ++h)
                    compare.hit(got.all_hits[i][h], expected.all_hits[i][h],
                                context + " all hits " + std::to_string(h));
            }
            for (std::size_t i = 0; i < points.size(); ++i)
                compare.nearest(got.nearest[i], expected.nearest[i], where + " point " + std::to_string(i));
            EXPECT_EQ(compare.mismatches.size(), 0u) << where;
            for (std::size_t m = 0; m < std::min<std::size_t>(compare.mismatches.size(), 4); ++m)
                ADD_FAILURE() << compare.mismatches[m];
        }
    }
}

// A scene moved across the ordinary range's edge and back by Accel::update: when the scale at which the
// structure sees it changes, the structure is built again at the new one; within one scale, the scaled copy
// is rewritten in place (and the BVHs refit it). Each update answers as a build on the moved geometry does.
TEST_P(DomainTest, UpdatesAcrossScalesAnswerAsBuilds) {
    const TestScene ordinary = ordinary_scene();
    const auto times = [&](float factor) {
        TestScene moved = ordinary;
        for (Triangle& t : moved.triangles)
            t = {t.v0 * factor, t.v1 * factor, t.v2 * factor};
        for (Sphere& sphere : moved.spheres)
            sphere = {sphere.center * factor, sphere.radius * factor, sphere.material};
        return moved;
    };
    // Sides 16 (ordinary), then 1.5 2^54 and 1.25 2^54 (one scale), 2^-70 (another), and 16 again.
    const std::vector<TestScene> frames = {ordinary, times(0x1.8p50f), times(0x1.4p50f), times(0x1p-74f),
                                           ordinary};
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const std::unique_ptr<Accel> updated = make_accel(GetParam());
        updated->build(frames[0].geometry(), build_options(test));
        for (std::size_t f = 1; f < frames.size(); ++f) {
            static_cast<void>(updated->update(frames[f].geometry()));
            const std::vector<Ray> rays = testing::random_rays(frames[f].geometry().bounds(), 2000, 80).rays;
            const std::unique_ptr<Accel> built = make_accel(GetParam());
            built->build(frames[f].geometry(), build_options(test));
            std::vector<Hit> expected(rays.size()), got(rays.size());
            built->intersect(rays, expected);
            updated->intersect(rays, got);
            std::size_t differences = 0, hits = 0;
            for (std::size_t i = 0; i < rays.size(); ++i) {
                hits += expected[i].hit() ? 1 : 0;
                differences += std::memcmp(&expected[i], &got[i], sizeof(Hit)) == 0 ? 0 : 1;
            }
            EXPECT_EQ(differences, 0u) << "frame " << f;
            EXPECT_GT(hits, rays.size() / 10) << "frame " << f;
            // The queries walk the updated tree of a BVH (another tree of their own otherwise).
            const GeometryQueries updated_queries(*updated, frames[f].geometry(), test);
            const GeometryQueries built_queries(*built, frames[f].geometry(), test);
            std::size_t query_differences = 0;
            for (std::size_t i = 0; i < 200; ++i) {
                std::vector<Hit> all, all_built;
                updated_queries.all_hits(rays[i], all);
                built_queries.all_hits(rays[i], all_built);
                query_differences += all.size() == all_built.size() ? 0 : 1;
                const Vec3f p = rays[i].origin;
                query_differences +=
                    updated_queries.nearest_point(p).distance == built_queries.nearest_point(p).distance ? 0
                                                                                                         : 1;
            }
            EXPECT_EQ(query_differences, 0u) << "frame " << f;
        }
    }
}

// The case that found it (docs/robustness.md, finding 29), against the exact answer: a triangle 4e13 across
// hit straight on, t = 3e13, and its barycentrics.
TEST_P(DomainTest, HugeTriangleHitStraightOn) {
    constexpr float kSize = 2e13f;
    const std::vector<Triangle> triangles = {{{-kSize, -kSize, 0}, {kSize, -kSize, 0}, {0, kSize, 0}}};
    const Geometry geometry{triangles, {}};
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const std::unique_ptr<Accel> accel = make_accel(GetParam());
        accel->build(geometry, build_options(test));
        const std::vector<Ray> rays = {{{0, 0, 3e13f}, {0, 0, -1}, 0, kInfinity},
                                       {{-1e13f, -1e13f, 3e13f}, {0, 0, -1}, 0, kInfinity},
                                       {{0, 0, 3e13f}, {0, 0, -0x1p-20f}, 0, kInfinity}};
        std::vector<Hit> hits(rays.size());
        accel->intersect(rays, hits);
        std::vector<std::uint8_t> occluded(rays.size());
        accel->occluded(rays, occluded);
        const GeometryQueries queries(*accel, geometry, test);
        for (std::size_t i = 0; i < rays.size(); ++i) {
            // The exact answer: the line meets z = 0 at t = 3e13 / |d_z|, at (x, y) = the origin's.
            const double t = 3e13 / -double(rays[i].direction.z);
            const double x = rays[i].origin.x, y = rays[i].origin.y;
            const double v = (y + kSize) / (2.0 * kSize), u = (x + kSize) / (2.0 * kSize) - 0.5 * v;
            const std::string context = std::string(GetParam()) + " ray " + std::to_string(i);
            ASSERT_EQ(hits[i].prim, 0) << context;
            EXPECT_NEAR(hits[i].t, t, 0x1p-22 * t) << context;
            EXPECT_NEAR(hits[i].u, u, 0x1p-22) << context;
            EXPECT_NEAR(hits[i].v, v, 0x1p-22) << context;
            EXPECT_EQ(occluded[i], 1) << context;
            std::vector<Hit> all;
            queries.all_hits(rays[i], all);
            EXPECT_EQ(all.size(), 1u) << context;
        }
        const NearestPoint nearest = queries.nearest_point({0, 0, 3e13f});
        EXPECT_EQ(nearest.prim, 0);
        EXPECT_EQ(nearest.distance, 3e13f);
    }
}

// Query points far from the scene (not bounded by the domain): the nearest point is brute force's, in the
// ordinary scene and in one scaled up, where the point scaled with it passes the float range. The wide
// BVHs bounded their boxes by squared distances in float, which overflowed to +inf, and found nothing.
TEST_P(DomainTest, FarQueryPointsFindTheNearestPoint) {
    for (const int exponent : {0, -60}) {
        const TestScene scene = scaled_scene(ordinary_scene(), exponent);
        const Geometry geometry = scene.geometry();
        const std::unique_ptr<Accel> accel = make_accel(GetParam());
        accel->build(geometry, build_options(TriangleTest::MollerTrumbore));
        const GeometryQueries queries(*accel, geometry, TriangleTest::MollerTrumbore);
        for (const Vec3f p : {Vec3f(1e30f, 0, 0), Vec3f(-3e38f, 2e38f, 1), Vec3f(0, 0x1p70f, -0x1p70f)}) {
            nearest::Search brute(geometry, Vec3d(p));
            for (std::uint32_t prim = 0; prim < geometry.size(); ++prim)
                brute.primitive(prim);
            const NearestPoint got = queries.nearest_point(p);
            EXPECT_EQ(got.prim, brute.best.prim)
                << scene.name << " (" << p.x << ", " << p.y << ", " << p.z << ")";
            EXPECT_EQ(got.distance, brute.best.distance) << scene.name;
        }
    }
}

// Just beyond the domain, every build and the queries' own tree are refused, naming the triangle.
TEST_P(DomainTest, SceneJustBeyondTheDomainIsRefused) {
    const float beyond = std::nextafter(kCoordinateLimit, kInfinity);
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}},
                                             {{-kCoordinateLimit, 0, 0}, {beyond, 0, 0}, {0, 1, 0}}};
    const Geometry geometry{triangles, {}};
    const std::unique_ptr<Accel> accel = make_accel(GetParam());
    try {
        accel->build(geometry, {});
        ADD_FAILURE() << "built";
    } catch (const std::invalid_argument& error) {
        EXPECT_NE(std::string(error.what()).find("triangle 1"), std::string::npos) << error.what();
    }
    EXPECT_THROW(GeometryQueries(geometry, TriangleTest::MollerTrumbore), std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(EveryStructure, DomainTest, ::testing::ValuesIn(accel_names()),
                         [](const auto& param_info) { return std::string(param_info.param); });

}  // namespace
}  // namespace lancer
