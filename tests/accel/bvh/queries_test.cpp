// GeometryQueries::all_hits against every primitive tested one by one: the same hits, each once, in order.
#include "lancer/queries.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <span>
#include <string_view>
#include <thread>
#include <vector>

#include "accel/bvh/nearest_point.hpp"
#include "accel/crossing_grid.hpp"
#include "accel/primitive_intersect.hpp"
#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

// Every primitive the ray hits within [tnear, tfar], tested one at a time, sorted as all_hits promises.
std::vector<Hit> every_hit(const Geometry& geometry, const Ray& ray, TriangleTest test) {
    std::vector<Hit> hits;
    if (!is_valid(ray)) return hits;
    dispatch_policies(test, false, [&]<class TriangleTestT, bool>() {
        const PreparedRay<TriangleTestT> prepared(ray);
        for (std::uint32_t prim = 0; prim < geometry.size(); ++prim) {
            Hit hit;
            if (intersect_primitive(geometry, prim, prepared, hit)) hits.push_back(hit);
        }
    });
    std::sort(hits.begin(), hits.end(),
              [](const Hit& a, const Hit& b) { return a.t < b.t || (a.t == b.t && a.prim < b.prim); });
    return hits;
}

TEST(GeometryQueries, AllHitsAreEveryPrimitivesHitInOrder) {
    const std::vector<Triangle> triangles = testing::knot_triangles(96);
    const Geometry geometry{triangles, {}};
    std::size_t rays_with_several = 0, checked = 0;
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const GeometryQueries queries(geometry, test);
        const Box3f bounds = geometry.bounds();
        for (const testing::RaySet& set :
             {testing::random_rays(bounds, 3000, 31), testing::vertex_and_edge_rays(triangles, 2000, 32),
              testing::axis_parallel_rays(bounds, 1000, 33), testing::clipped_rays(bounds, 1000, 34)}) {
            for (const Ray& ray : set.rays) {
                std::vector<Hit> hits;
                queries.all_hits(ray, hits);
                const std::vector<Hit> expected = every_hit(geometry, ray, test);
                ASSERT_EQ(hits.size(), expected.size()) << set.name;
                for (std::size_t i = 0; i < hits.size(); ++i) {
                    ASSERT_EQ(hits[i].prim, expected[i].prim) << set.name;
                    ASSERT_EQ(hits[i].t, expected[i].t) << set.name;
                    ASSERT_EQ(hits[i].u, expected[i].u) << set.name;
                }
                rays_with_several += hits.size() > 1 ? 1 : 0;
                ++checked;
            }
        }
    }
    EXPECT_EQ(checked, 14000u);
    EXPECT_GT(rays_with_several, 1000u);  // the knot is crossed several times by most rays that reach it
}

TEST(GeometryQueries, AppendsAndIgnoresInvalidRays) {
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const GeometryQueries queries({triangles, {}}, TriangleTest::Watertight);
    std::vector<Hit> hits(1);  // kept: all_hits appends
    queries.all_hits({{0.2f, 0.2f, 1}, {0, 0, -1}, 0.0f, kInfinity}, hits);
    ASSERT_EQ(hits.size(), 2u);
    EXPECT_EQ(hits[1].prim, 0);
    EXPECT_EQ(hits[1].t, 1.0f);
    queries.all_hits({{0.2f, 0.2f, 1}, {0, 0, 0}, 0.0f, kInfinity}, hits);  // zero direction: invalid
    EXPECT_EQ(hits.size(), 2u);
}

// The distance from p to a triangle by another route: to the plane when p projects inside, else to the
// nearest of the three edges as segments.
double distance_to_triangle(const Triangle& tri, const Vec3f& point) {
    const auto to_d = [](const Vec3f& a) { return std::array<double, 3>{a.x, a.y, a.z}; };
    const auto sub = [](std::array<double, 3> a, std::array<double, 3> b) {
        return std::array<double, 3>{a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    };
    const auto dot3 = [](std::array<double, 3> a, std::array<double, 3> b) {
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    };
    const auto cross3 = [](std::array<double, 3> a, std::array<double, 3> b) {
        return std::array<double, 3>{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                                     a[0] * b[1] - a[1] * b[0]};
    };
    const auto p = to_d(point);
    const std::array<std::array<double, 3>, 3> v = {to_d(tri.v0), to_d(tri.v1), to_d(tri.v2)};
    double best = std::numeric_limits<double>::infinity();
    for (int e = 0; e < 3; ++e) {
        const auto a = v[e], b = v[(e + 1) % 3];
        const auto ab = sub(b, a);
        const double length2 = dot3(ab, ab);
        const double t = length2 > 0.0 ? std::clamp(dot3(sub(p, a), ab) / length2, 0.0, 1.0) : 0.0;
        const auto d = sub(p, {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]});
        best = std::min(best, std::sqrt(dot3(d, d)));
    }
    const auto n = cross3(sub(v[1], v[0]), sub(v[2], v[0]));
    const double n2 = dot3(n, n);
    if (n2 > 0.0) {
        bool inside = true;
        for (int e = 0; e < 3; ++e)
            inside = inside && dot3(cross3(sub(v[(e + 1) % 3], v[e]), sub(p, v[e])), n) >= 0.0;
        if (inside) best = std::min(best, std::fabs(dot3(sub(p, v[0]), n)) / std::sqrt(n2));
    }
    return best;
}

TEST(GeometryQueries, NearestPointIsTheNearestOfEveryTriangle) {
    const std::vector<Triangle> triangles = testing::knot_triangles(48);
    const Geometry geometry{triangles, {}};
    const GeometryQueries queries(geometry, TriangleTest::Watertight);
    const Box3f bounds = geometry.bounds();
    std::mt19937 rng(41);
    std::uniform_real_distribution<float> unit(-0.5f, 1.5f);
    for (int n = 0; n < 2000; ++n) {
        // Points around the knot and, one in four, exactly on one of its vertices.
        Vec3f p = bounds.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * bounds.extent();
        if (n % 4 == 0) p = triangles[static_cast<std::size_t>(rng()) % triangles.size()].v1;
        double expected = std::numeric_limits<double>::infinity();
        for (const Triangle& tri : triangles)
            expected = std::min(expected, distance_to_triangle(tri, p));
        const NearestPoint nearest = queries.nearest_point(p);
        ASSERT_GE(nearest.prim, 0);
        EXPECT_NEAR(nearest.distance, expected, 1e-5 * (1.0 + expected)) << n;
        EXPECT_NEAR(length(nearest.point - p), nearest.distance, 1e-5 * (1.0 + expected)) << n;
        // The point lies on its triangle: its barycentric weights rebuild it.
        const Triangle& tri = triangles[static_cast<std::size_t>(nearest.prim)];
        const Vec3f rebuilt = tri.v0 + nearest.u * (tri.v1 - tri.v0) + nearest.v * (tri.v2 - tri.v0);
        EXPECT_LT(length(rebuilt - nearest.point), 1e-5f * (1.0f + length(bounds.extent()))) << n;
        EXPECT_GE(nearest.u, 0.0f);
        EXPECT_GE(nearest.v, 0.0f);
        EXPECT_LE(nearest.u + nearest.v, 1.0f + 1e-6f);
    }
    EXPECT_EQ(GeometryQueries({}, TriangleTest::Watertight).nearest_point({0, 0, 0}).prim, -1);
}

// The nearest point by every primitive in turn, with the tree walks' own kernel and tie rule.
NearestPoint brute_nearest(const Geometry& geometry, const Vec3f& p) {
    nearest::Search search(geometry, Vec3d(p));
    for (std::uint32_t prim = 0; prim < geometry.size(); ++prim)
        search.primitive(prim);
    return search.best;
}

// Points around the knot, on its vertices, edge midpoints and centroids, and far away.
std::vector<Vec3f> query_points(std::span<const Triangle> triangles, const Box3f& bounds) {
    std::mt19937 rng(43);
    std::uniform_real_distribution<float> unit(-0.5f, 1.5f);
    std::vector<Vec3f> points;
    for (int n = 0; n < 600; ++n)
        points.push_back(bounds.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * bounds.extent());
    for (std::size_t i = 0; i < triangles.size(); i += 7) {
        const Triangle& tri = triangles[i];
        points.push_back(tri.v0);
        points.push_back((tri.v1 + tri.v2) * 0.5f);
        points.push_back((tri.v0 + tri.v1 + tri.v2) / 3.0f);
    }
    for (int n = 0; n < 50; ++n)
        points.push_back(Vec3f(unit(rng), unit(rng), unit(rng)) * 1e5f);
    return points;
}

// The BVH family's queries walk the structure's own tree (no second tree built) and give brute force's
// answers bit for bit; the others build their own.
TEST(GeometryQueries, WalkTheStructuresOwnBvhWithBruteForcesAnswers) {
    std::vector<Triangle> triangles = testing::knot_triangles(48);
    triangles.push_back({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}});  // zero area
    const std::vector<Sphere> spheres = {{{3, 0, 0}, 0.5f, 0}};
    const Geometry geometry{triangles, spheres};
    const std::vector<Vec3f> points = query_points(triangles, geometry.bounds());
    std::vector<NearestPoint> expected;
    for (const Vec3f& p : points)
        expected.push_back(brute_nearest(geometry, p));
    for (const std::string_view name : accel_names()) {
        if (name.starts_with("embree")) continue;
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(geometry, build_options(TriangleTest::Watertight));
        const GeometryQueries queries(*accel, geometry, TriangleTest::Watertight);
        const bool bvh_family = name.starts_with("bvh");
        EXPECT_EQ(queries.walks_accel(), bvh_family) << name;
        for (std::size_t i = 0; i < points.size(); ++i) {
            const NearestPoint nearest = queries.nearest_point(points[i]);
            ASSERT_EQ(nearest.prim, expected[i].prim) << name << " point " << i;
            ASSERT_EQ(nearest.distance, expected[i].distance) << name << " point " << i;
            ASSERT_EQ(nearest.point.x, expected[i].point.x) << name << " point " << i;
            ASSERT_EQ(nearest.point.y, expected[i].point.y) << name << " point " << i;
            ASSERT_EQ(nearest.point.z, expected[i].point.z) << name << " point " << i;
            ASSERT_EQ(nearest.u, expected[i].u) << name << " point " << i;
            ASSERT_EQ(nearest.v, expected[i].v) << name << " point " << i;
        }
        const testing::RaySet rays = testing::random_rays(geometry.bounds(), 1000, 44);
        for (const Ray& ray : rays.rays) {
            std::vector<Hit> hits;
            queries.all_hits(ray, hits);
            const std::vector<Hit> all = every_hit(geometry, ray, TriangleTest::Watertight);
            ASSERT_EQ(hits.size(), all.size()) << name;
            for (std::size_t k = 0; k < hits.size(); ++k) {
                ASSERT_EQ(hits[k].prim, all[k].prim) << name;
                ASSERT_EQ(hits[k].t, all[k].t) << name;
            }
        }
    }
}

// The distinct t among all_hits' hits: the crossings count_crossings must give.
std::uint32_t distinct_times(const GeometryQueries& queries, const Ray& ray) {
    std::vector<Hit> hits;
    queries.all_hits(ray, hits);
    std::uint32_t distinct = 0;
    for (std::size_t h = 0; h < hits.size(); ++h)
        distinct += (h == 0 || hits[h].t != hits[h - 1].t) ? 1 : 0;
    return distinct;
}

// Occupancy's origins for one direction: random points around the geometry, and points around triangles:
// their corners and edge midpoints (rays from the surface), and the same moved back along the direction
// (rays through shared vertices and edges).
std::vector<Vec3f> crossing_origins(std::span<const Triangle> triangles, const Box3f& bounds, Vec3f direction,
                                    std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::uniform_int_distribution<std::size_t> pick(0, triangles.size() - 1);
    const Box3f around = bounds.grown(0.1f * length(bounds.extent()));
    const float step = 0.02f * length(bounds.extent());
    std::vector<Vec3f> origins;
    for (int n = 0; n < 2000; ++n)
        origins.push_back(around.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * around.extent());
    for (int n = 0; n < 300; ++n) {
        const Triangle& tri = triangles[pick(rng)];
        for (const Vec3f& p : {tri.v0, tri.v1, tri.v2, (tri.v0 + tri.v1) * 0.5f, (tri.v1 + tri.v2) * 0.5f}) {
            origins.push_back(p);
            origins.push_back(p - direction * (step * unit(rng)));
        }
    }
    return origins;
}

// count_crossings counts the distinct t of all_hits' hits, bit for bit, by its grid (a batch of more than a
// ray per four triangles) and by tree walks (a smaller batch), on bvh8_packet's, bvh8's and the binary tree,
// both triangle tests: on a closed icosphere and a knot, on a plane of triangles whose vertices six share,
// along directions off the axes, along (1, 1, 1) through the plane's edges and along an axis, and from
// origins far away (conditioned rays, which walk the tree).
TEST(GeometryQueries, CountCrossingsCountsAllHitsDistinctTimes) {
    std::vector<Triangle> closed;
    make_icosphere(3, Vec3f(0.0f), 1.0f).append_triangles(closed);
    make_torus_knot(48, 12).append_triangles(closed);
    std::vector<Triangle> plane = testing::planar_grid_triangles(40);
    const Vec3f directions[] = {normalize(Vec3f(0.118f, -0.286f, 0.432f)),
                                normalize(Vec3f(-0.7f, 0.2f, -0.3f)), normalize(Vec3f(1.0f, 1.0f, 1.0f)),
                                Vec3f(0.0f, 0.0f, -1.0f)};
    std::size_t checked = 0, odd = 0, several = 0;
    for (const std::vector<Triangle>* triangles : std::array{&closed, &plane}) {
        const Geometry geometry{*triangles, {}};
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            for (const std::string_view name : {"bvh8_packet", "bvh8", "bvh"}) {
                const std::unique_ptr<Accel> accel = make_accel(name);
                accel->build(geometry, build_options(test));
                const GeometryQueries queries(*accel, geometry, test);
                for (std::uint32_t d = 0; d < std::size(directions); ++d) {
                    std::vector<Vec3f> origins =
                        crossing_origins(*triangles, geometry.bounds(), directions[d], 51 + d);
                    for (std::size_t i = 0; i < 20; ++i)
                        origins[i] = origins[i] + Vec3f(3e30f, -2e30f, 1e30f);  // far origins
                    ASSERT_GE(4 * origins.size(), geometry.size());             // the grid
                    std::vector<std::uint32_t> crossings(origins.size()), walked(origins.size());
                    queries.count_crossings(directions[d], origins, crossings, 2);
                    for (std::size_t first = 0; first < origins.size(); first += 64) {  // tree walks
                        const std::size_t count = std::min<std::size_t>(64, origins.size() - first);
                        ASSERT_LT(4 * count, geometry.size());
                        queries.count_crossings(directions[d], std::span(origins).subspan(first, count),
                                                std::span(walked).subspan(first, count), 1);
                    }
                    for (std::size_t i = 0; i < origins.size(); ++i) {
                        const std::uint32_t expected =
                            distinct_times(queries, {origins[i], directions[d], 0.0f, kInfinity});
                        ASSERT_EQ(crossings[i], expected) << name << " direction " << d << " origin " << i;
                        ASSERT_EQ(walked[i], expected) << name << " direction " << d << " origin " << i;
                        odd += crossings[i] % 2, several += crossings[i] > 1 ? 1 : 0;
                    }
                    checked += origins.size();
                }
            }
        }
    }
    EXPECT_EQ(checked, 2u * 2u * 3u * 4u * 5000u);
    EXPECT_GT(odd,
              checked / 10);  // origins inside the sphere and the knot, and rays from the plane's surface
    EXPECT_GT(several, checked / 20);
}

// An icosphere of radius 1 in bvh8_packet with the watertight test, and its queries; the triangles may be
// moved in place and the structure updated.
struct SphereQueries {
    std::vector<Triangle> triangles;
    Geometry geometry;
    std::unique_ptr<Accel> accel = make_accel("bvh8_packet");
    std::unique_ptr<GeometryQueries> queries;

    explicit SphereQueries(int subdivisions) {
        make_icosphere(subdivisions, Vec3f(0.0f), 1.0f).append_triangles(triangles);
        geometry = {triangles, {}};
        accel->build(geometry, build_options(TriangleTest::Watertight));
        queries = std::make_unique<GeometryQueries>(*accel, geometry, TriangleTest::Watertight);
    }
};

// With more than 2^11 cells the radix sort of the listed rays by cell takes two passes, the second counted
// and scattered in chunks of its own: every ray still gets its own crossings, on 1 and 2 threads.
TEST(GeometryQueries, CountCrossingsThroughATwoPassSort) {
    const SphereQueries sphere(5);
    const std::vector<Triangle>& triangles = sphere.triangles;
    const Geometry& geometry = sphere.geometry;
    const GeometryQueries& queries = *sphere.queries;
    const Vec3f direction = normalize(Vec3f(0.118f, -0.286f, 0.432f));
    // The grid count_crossings makes (about a cell per two triangles): more than 2^11 cells.
    ASSERT_GT(CrossingGrid(geometry, geometry.bounds(), direction, geometry.size() / 2, 1).cell_count(),
              std::size_t{1} << 11);
    std::vector<Vec3f> origins;
    for (int round = 0; round < 3; ++round) {
        const std::vector<Vec3f> more = crossing_origins(triangles, geometry.bounds(), direction,
                                                         200 + static_cast<std::uint32_t>(round));
        origins.insert(origins.end(), more.begin(), more.end());
    }
    ASSERT_GE(4 * origins.size(), geometry.size());  // the grid, not tree walks
    std::size_t inside = 0;
    for (const int threads : {1, 2}) {
        std::vector<std::uint32_t> crossings(origins.size());
        queries.count_crossings(direction, origins, crossings, threads);
        for (std::size_t i = 0; i < origins.size(); ++i) {
            ASSERT_EQ(crossings[i], distinct_times(queries, {origins[i], direction, 0.0f, kInfinity}))
                << "origin " << i << ", " << threads << " threads";
            inside += crossings[i] % 2;
        }
    }
    EXPECT_GT(inside, origins.size() / 10);
}

// count_crossings keeps its grid of a direction between calls: after the triangles move (an update that
// rewrites the same arrays in place), the next call along that direction counts the moved triangles.
TEST(GeometryQueries, CountCrossingsFollowsTheTrianglesAfterAnUpdate) {
    SphereQueries sphere(3);
    std::vector<Triangle>& triangles = sphere.triangles;
    const Geometry& geometry = sphere.geometry;
    Accel* const accel = sphere.accel.get();
    const GeometryQueries& queries = *sphere.queries;
    const Vec3f direction = normalize(Vec3f(0.118f, -0.286f, 0.432f));
    const std::vector<Vec3f> origins = crossing_origins(triangles, geometry.bounds(), direction, 7);
    std::vector<std::uint32_t> crossings(origins.size());
    queries.count_crossings(direction, origins, crossings, 2);  // the grid of the sphere where it was
    for (Triangle& tri : triangles) {
        const Vec3f shift(0.6f, -0.4f, 0.0f);
        tri = {tri.v0 + shift, tri.v1 + shift, tri.v2 + shift};
    }
    accel->update(geometry);
    queries.count_crossings(direction, origins, crossings, 2);
    std::size_t changed = 0;
    for (std::size_t i = 0; i < origins.size(); ++i) {
        const std::uint32_t expected = distinct_times(queries, {origins[i], direction, 0.0f, kInfinity});
        ASSERT_EQ(crossings[i], expected) << "origin " << i;
        changed += expected % 2 != 0 && length(origins[i]) > 1.0f ? 1 : 0;  // outside before, inside now
    }
    EXPECT_GT(changed, 100u);
}

// Calls from several threads at once, along the same and other directions, give each call's own answers
// (the grids and arrays kept between calls are shared by them).
TEST(GeometryQueries, CountCrossingsFromSeveralThreadsAtOnce) {
    std::vector<Triangle> triangles;
    make_torus_knot(48, 12).append_triangles(triangles);
    const Geometry geometry{triangles, {}};
    const std::unique_ptr<Accel> accel = make_accel("bvh8_packet");
    accel->build(geometry, build_options(TriangleTest::MollerTrumbore));
    const GeometryQueries queries(*accel, geometry, TriangleTest::MollerTrumbore);
    const Vec3f directions[] = {normalize(Vec3f(0.118f, -0.286f, 0.432f)),
                                normalize(Vec3f(-0.7f, 0.2f, -0.3f))};
    constexpr int kCallers = 4;
    std::vector<std::vector<Vec3f>> origins;
    std::vector<std::vector<std::uint32_t>> expected(kCallers), answers(kCallers);
    for (int c = 0; c < kCallers; ++c) {
        const Vec3f& direction = directions[c % 2];
        origins.push_back(
            crossing_origins(triangles, geometry.bounds(), direction, 90 + static_cast<std::uint32_t>(c)));
        for (const Vec3f& origin : origins.back())
            expected[c].push_back(distinct_times(queries, {origin, direction, 0.0f, kInfinity}));
        answers[c].resize(origins.back().size());
    }
    for (int round = 0; round < 5; ++round) {
        std::vector<std::thread> callers;
        for (int c = 0; c < kCallers; ++c)
            callers.emplace_back(
                [&, c] { queries.count_crossings(directions[c % 2], origins[c], answers[c], 1); });
        for (std::thread& caller : callers)
            caller.join();
        for (int c = 0; c < kCallers; ++c)
            ASSERT_EQ(answers[c], expected[c]) << "round " << round << " caller " << c;
    }
}

}  // namespace
}  // namespace lancer
