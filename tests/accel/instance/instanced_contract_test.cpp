// The numerical contract of two-level scenes (lancer/instances.hpp): every hit against the same scene
// flattened in double precision, the watertight test inside instances, and the tie rule. The bound every hit
// is held to: docs/numerical-contract.md, "Instances".
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "instanced_fixture.hpp"
#include "lancer/generate.hpp"
#include "lancer/instances.hpp"
#include "lancer/vec3d.hpp"
#include "support/ray_sets.hpp"

namespace lancer::testing {
namespace {

// The contract's bound on a hit's t, in the object's frame (where t is the same): the object ray rounds to
// 2^-24 of its coordinates and the kernel to a few 2^-24 of the distance to the triangle, which moves the
// hit along the ray by that distance over the cosine between the ray and the triangle.
constexpr double kBoundFactor = 0x1p-19;
// A hit's barycentrics may lie this far outside [0, 1] (a hit within the kernels' tolerance of an edge), and
// an exact hit at least this far inside every edge must be found; more where the bound on t moves the hit
// point by more (barycentric_bound).
constexpr double kEdgeMargin = 1e-3;

// The exact-enough intersection of a line with a triangle's plane, in double: t and barycentrics, whatever
// their range; none when the line is parallel to the plane.
struct PlaneHit {
    double t = 0.0, u = 0.0, v = 0.0;
    double cosine = 0.0;  // |cos| between the ray and the triangle's normal
    [[nodiscard]] double edge_distance() const { return std::min({u, v, 1.0 - u - v}); }
};

bool plane_hit(const Vec3d& o, const Vec3d& d, const Vec3d& v0, const Vec3d& v1, const Vec3d& v2,
               PlaneHit& hit) {
    const Vec3d e1 = v1 - v0, e2 = v2 - v0;
    const Vec3d p = cross(d, e2);
    const double det = dot(e1, p);
    if (det == 0.0) return false;
    const Vec3d t = o - v0;
    const Vec3d q = cross(t, e1);
    hit.u = dot(t, p) / det;
    hit.v = dot(d, q) / det;
    hit.t = dot(e2, q) / det;
    const Vec3d n = cross(e1, e2);
    hit.cosine = std::fabs(dot(n, d)) / (length(n) * length(d));
    return true;
}

// The bound on |t - t_exact| of a hit on `placed` at parameter t, computed in the instance's frame.
double t_bound(const FlatScene& flat, const FlatScene::Placed& placed, const Ray& ray, double t,
               double cosine) {
    // In the object's frame: the object ray and the object's vertices.
    const Affine& affine = flat.transforms[static_cast<std::size_t>(placed.instance)];
    // |o'| + t |d'| + the vertices' size, over |d'| cos, with |o'| and |d'| bounded through the inverse's
    // norm by the world's (the same parameter t): ||A^-1|| (|o - b| + t |d|).
    double inverse_norm = 0.0;
    {
        // ||A^-1|| >= 1 / ||A||; bound it above by the smallest singular value's reciprocal through the
        // determinant: a cheap overestimate is enough for a bound the test states.
        const double(&a)[3][3] = affine.a;
        const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                           a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        double norm_sq = 0.0;
        for (const auto& row : a)
            norm_sq += row[0] * row[0] + row[1] * row[1] + row[2] * row[2];
        inverse_norm = norm_sq / std::fabs(det);  // ||adj|| <= ||A||_F^2 (Frobenius), over |det|
    }
    const Vec3d o(ray.origin), d(ray.direction);
    const Vec3d b(affine.b[0], affine.b[1], affine.b[2]);
    const double reach = inverse_norm * (length(o - b) + std::fabs(t) * length(d));
    const double object_size = flat.object_sizes[static_cast<std::size_t>(placed.instance)];
    // |d'| >= |d| / ||A||.
    double norm_sq = 0.0;
    for (const auto& row : affine.a)
        norm_sq += row[0] * row[0] + row[1] * row[1] + row[2] * row[2];
    const double direction_length = length(d) / std::sqrt(norm_sq);
    return kBoundFactor * (reach + object_size) / (direction_length * std::max(cosine, 1e-12));
}

// How far a hit's barycentrics may stray, for a hit point `distance` from the exact one: that distance over
// the triangle's smallest altitude, and at least kEdgeMargin.
double barycentric_bound(const FlatScene::Placed& placed, double distance) {
    const Vec3d e0 = placed.v1 - placed.v0, e1 = placed.v2 - placed.v1, e2 = placed.v0 - placed.v2;
    const double longest = std::max({length(e0), length(e1), length(e2)});
    const double smallest_altitude = length(cross(e0, e2)) / longest;
    return std::max(kEdgeMargin, distance / smallest_altitude);
}

struct Verdict {
    std::size_t rays = 0, hits = 0, checked_misses = 0, failures = 0;
    std::string first_failure;
    void fail(std::size_t ray, const std::string& what) {
        if (failures++ == 0) first_failure = "ray " + std::to_string(ray) + ": " + what;
    }
};

// The nearest exact hit of a ray in the flattened scene that every structure must find: well inside a
// triangle, not grazing, well inside [tnear, tfar]; t is infinite when there is none.
struct ExactNearest {
    double t = std::numeric_limits<double>::infinity();
    double bound = 0.0;  // t_bound at that hit
};

std::vector<ExactNearest> exact_nearest_hits(const FlatScene& flat, std::span<const Ray> rays) {
    std::vector<ExactNearest> nearest(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Ray& ray = rays[i];
        if (!is_valid(ray)) continue;
        const Vec3d o(ray.origin), d(ray.direction);
        for (const FlatScene::Placed& placed : flat.triangles) {
            PlaneHit exact;
            if (!plane_hit(o, d, placed.v0, placed.v1, placed.v2, exact)) continue;
            // A hit beyond the float range is none (docs/numerical-contract.md, "Ray conditioning").
            if (exact.cosine < 1e-3 || exact.t > std::numeric_limits<float>::max()) continue;
            const double bound = t_bound(flat, placed, ray, exact.t, exact.cosine);
            if (exact.edge_distance() < barycentric_bound(placed, bound * length(d))) continue;
            if (exact.t < double(ray.tnear) + bound || exact.t > double(ray.tfar) - bound) continue;
            if (exact.t < nearest[i].t) nearest[i] = {exact.t, bound};
        }
    }
    return nearest;
}

// Every answer of `scene` held to the flattened scene: a reported hit lies on its triangle (barycentrics
// within kEdgeMargin) at the exact t within the bound, and no exact hit well inside a triangle lies nearer
// than it by more than the bound (`nearest`, of exact_nearest_hits), nor is missed.
Verdict check_against_flat(const InstancedScene& scene, const Fixture& fixture, const FlatScene& flat,
                           std::span<const Ray> rays, std::span<const ExactNearest> nearest) {
    std::vector<InstanceHit> hits(rays.size());
    scene.intersect(rays, hits);
    std::vector<std::uint8_t> occluded(rays.size());
    scene.occluded(rays, occluded);
    Verdict verdict;
    verdict.rays = rays.size();
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Ray& ray = rays[i];
        const InstanceHit& hit = hits[i];
        if (!is_valid(ray)) {
            if (hit.hit() || occluded[i] != 0) verdict.fail(i, "an invalid ray hits");
            continue;
        }
        if ((occluded[i] != 0) != hit.hit()) verdict.fail(i, "occluded disagrees with intersect");
        const Vec3d o(ray.origin), d(ray.direction);
        if (hit.hit()) {
            ++verdict.hits;
            if (hit.t < ray.tnear || hit.t > ray.tfar) verdict.fail(i, "t outside [tnear, tfar]");
            if (hit.instance < 0 || static_cast<std::size_t>(hit.instance) >= fixture.transforms.size() ||
                static_cast<std::uint32_t>(hit.object) !=
                    fixture.objects[static_cast<std::size_t>(hit.instance)]) {
                verdict.fail(i, "instance or object out of range");
                continue;
            }
            const auto& triangles = fixture.object_triangles[static_cast<std::size_t>(hit.object)];
            if (hit.prim < 0 || static_cast<std::size_t>(hit.prim) >= triangles.size()) {
                verdict.fail(i, "primitive out of range");
                continue;
            }
            const Affine& affine = flat.transforms[static_cast<std::size_t>(hit.instance)];
            const Triangle& tri = triangles[static_cast<std::size_t>(hit.prim)];
            const FlatScene::Placed placed{hit.instance, hit.prim, affine.point(tri.v0), affine.point(tri.v1),
                                           affine.point(tri.v2)};
            PlaneHit exact;
            if (!plane_hit(o, d, placed.v0, placed.v1, placed.v2, exact)) {
                verdict.fail(i, "the reported triangle is parallel to the ray");
                continue;
            }
            const double bound = t_bound(flat, placed, ray, exact.t, exact.cosine);
            if (std::fabs(hit.t - exact.t) > bound) {
                verdict.fail(i, "t " + std::to_string(hit.t) + " against exact " + std::to_string(exact.t) +
                                    ", bound " + std::to_string(bound));
            }
            const double bary = barycentric_bound(placed, bound * length(d));
            if (exact.edge_distance() < -bary) verdict.fail(i, "the hit lies off its triangle");
            if (std::fabs(hit.u - exact.u) > bary || std::fabs(hit.v - exact.v) > bary)
                verdict.fail(i, "barycentrics off the exact ones");
        }
        if (nearest[i].t == std::numeric_limits<double>::infinity()) continue;
        ++verdict.checked_misses;
        if (!hit.hit()) {
            verdict.fail(i, "missed an exact hit at t = " + std::to_string(nearest[i].t));
        } else if (hit.t > nearest[i].t + nearest[i].bound) {
            verdict.fail(i, "hit at t = " + std::to_string(hit.t) + " behind an exact hit at " +
                                std::to_string(nearest[i].t));
        }
    }
    return verdict;
}

class InstancedOracle : public ::testing::TestWithParam<Case> {};

// The fixture, its flattened scene, the ray sets over the scene's bounds and their exact nearest hits: the
// same for every case, so made once (the cases run in one process: ONE_PROCESS in
// tests/accel/CMakeLists.txt).
struct OracleRays {
    Fixture fixture = random_fixture(5, 24);
    FlatScene flat = flatten(fixture);
    Box3f bounds = make_scene(fixture, "bvh", TriangleTest::Watertight).bounds();
    std::vector<RaySet> sets = {testing::random_rays(bounds, 1500, 1),
                                testing::axis_parallel_rays(bounds, 600, 2),
                                testing::clipped_rays(bounds, 600, 3), testing::hostile_rays(bounds),
                                inside_and_grazing_rays(fixture, flat, 600, 4)};
    std::vector<std::vector<ExactNearest>> nearest;  // by set

    OracleRays() {
        for (const RaySet& set : sets)
            nearest.push_back(exact_nearest_hits(flat, set.rays));
    }
};

const OracleRays& oracle_rays() {
    static const OracleRays rays;
    return rays;
}

// Every object structure, both triangle tests: random rays, axis-parallel and zero-component rays, clipped
// intervals, NaN and other invalid rays, rays from inside instances and grazing rays, all against the scene
// flattened in double.
TEST_P(InstancedOracle, EveryHitWithinTheBoundOfTheFlattenedScene) {
    const OracleRays& oracle = oracle_rays();
    const InstancedScene scene = make_scene(oracle.fixture, GetParam().accel, GetParam().test);
    // The instances' boxes, hence the rays, do not depend on the object's structure.
    ASSERT_EQ(scene.bounds().lo, oracle.bounds.lo);
    ASSERT_EQ(scene.bounds().hi, oracle.bounds.hi);
    for (std::size_t k = 0; k < oracle.sets.size(); ++k) {
        const RaySet& set = oracle.sets[k];
        const Verdict verdict =
            check_against_flat(scene, oracle.fixture, oracle.flat, set.rays, oracle.nearest[k]);
        std::printf("%s %s: %zu rays, %zu hits, %zu exact hits checked\n",
                    std::string(GetParam().accel).c_str(), set.name.c_str(), verdict.rays, verdict.hits,
                    verdict.checked_misses);
        EXPECT_EQ(verdict.failures, 0u) << set.name << ": " << verdict.first_failure;
        if (set.name != "hostile") {
            EXPECT_GT(verdict.checked_misses, set.rays.size() / 20) << set.name;
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Objects, InstancedOracle,
                         ::testing::Values(Case{"bvh8", TriangleTest::Watertight},
                                           Case{"bvh8", TriangleTest::MollerTrumbore},
                                           Case{"bvh8_packet", TriangleTest::Watertight},
                                           Case{"bvh8_packet", TriangleTest::MollerTrumbore},
                                           Case{"bvh", TriangleTest::Watertight}),
                         case_name);

// Rays from inside instanced icospheres aimed at the world images of their vertices and edge points: the
// watertight test lets none through, whatever the transform (Moller-Trumbore's leaks are counted beside, to
// show the rays find the cracks).
std::size_t count_leaks(std::string_view accel, TriangleTest test, std::size_t& rays_out) {
    const TriangleMesh sphere = make_icosphere(3);
    Fixture fixture;
    fixture.object_triangles.push_back(sphere.triangles());
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), scale(0.2f, 3.0f), angle(0.0f, 6.2831853f);
    // The first exact in float (a signed axis permutation times 2, no translation): its object rays are
    // those aimed at the vertices in the object's frame, bit for bit, which Moller-Trumbore leaks through.
    Transform exact;
    exact.m[0][0] = 0.0f, exact.m[0][1] = 2.0f, exact.m[1][1] = 0.0f, exact.m[1][2] = -2.0f;
    exact.m[2][2] = 0.0f, exact.m[2][0] = 2.0f;
    fixture.transforms.push_back(exact);
    fixture.objects.push_back(0);
    for (int i = 0; i < 6; ++i) {
        fixture.transforms.push_back(
            Transform::translation({40.0f * unit(rng), 40.0f * unit(rng), 40.0f * unit(rng)}) *
            Transform::rotation({unit(rng), unit(rng), 1.0f}, angle(rng)) *
            Transform::scaling({scale(rng), scale(rng), scale(rng)}));
        fixture.objects.push_back(0);
    }
    const InstancedScene scene = make_scene(fixture, accel, test);
    std::vector<Ray> rays;
    std::vector<std::int32_t> own;  // the instance each ray starts inside
    std::uniform_real_distribution<float> fraction(0.0f, 1.0f);
    for (const Transform& t : fixture.transforms) {
        std::vector<Vec3f> targets(sphere.positions.begin(), sphere.positions.end());
        for (std::size_t tri = 0; tri < sphere.triangle_count(); ++tri) {
            for (int corner = 0; corner < 3; ++corner) {
                const Vec3f a = sphere.positions[sphere.indices[3 * tri + static_cast<std::size_t>(corner)]];
                const Vec3f b =
                    sphere.positions[sphere.indices[3 * tri + static_cast<std::size_t>(corner + 1) % 3]];
                targets.push_back(0.5f * (a + b));
                const float f = fraction(rng);
                targets.push_back((1.0f - f) * a + f * b);
            }
        }
        for (const Vec3f& inside : {Vec3f(0.0f), Vec3f(0.1f, -0.2f, 0.3f), Vec3f(-0.3f, 0.25f, -0.6f)}) {
            const Vec3f origin = t.point(inside);
            for (const Vec3f& target : targets) {
                rays.push_back({origin, t.point(target) - origin, 0.0f, kInfinity});
                own.push_back(static_cast<std::int32_t>(&t - fixture.transforms.data()));
            }
        }
    }
    std::vector<std::uint8_t> occluded(rays.size());
    scene.occluded(rays, occluded);
    std::vector<InstanceHit> hits(rays.size());
    scene.intersect(rays, hits);
    // A ray from inside an instance leaks when it leaves that instance unhit: it misses, or hits another.
    std::size_t leaks = 0;
    for (std::size_t i = 0; i < rays.size(); ++i)
        leaks += (occluded[i] == 0 || hits[i].instance != own[i]) ? 1 : 0;
    rays_out = rays.size();
    return leaks;
}

TEST(InstancedScene, NoLeakThroughSharedVerticesAndEdgesOfInstancedIcospheres) {
    for (const std::string_view accel : {"bvh8", "bvh8_packet"}) {
        std::size_t rays = 0, moller_rays = 0;
        const std::size_t watertight = count_leaks(accel, TriangleTest::Watertight, rays);
        const std::size_t moller = count_leaks(accel, TriangleTest::MollerTrumbore, moller_rays);
        std::printf(
            "%s: %zu rays at instanced vertices and edges; leaks: watertight %zu, moller-trumbore %zu\n",
            std::string(accel).c_str(), rays, watertight, moller);
        EXPECT_GT(rays, 100000u);
        EXPECT_EQ(watertight, 0u) << accel;
        EXPECT_GT(moller, 0u) << "the rays no longer reach the cracks between triangles";
    }
}

// Rays from origins up to `distance` from `centre` on each axis, aimed at points within 0.5 of it.
std::vector<Ray> rays_at_centre(const Vec3f& centre, float distance, int count, std::uint32_t seed) {
    std::vector<Ray> rays;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    for (int i = 0; i < count; ++i) {
        const Vec3f origin = centre + distance * Vec3f(unit(rng), unit(rng), unit(rng));
        rays.push_back(
            {origin, centre + 0.5f * Vec3f(unit(rng), unit(rng), unit(rng)) - origin, 0.0f, kInfinity});
    }
    return rays;
}

// At equal t the smaller instance id wins: two instances of one object under the same transform, added in
// either order of the boxes' walk. From origins near the instances and from far ones, which the walk moves
// near each object before tracing it (docs/numerical-contract.md, "Far origins"), in a batch (whose rays walk
// the top level together) and ray by ray.
TEST(InstancedScene, TiesGoToTheSmallerInstanceId) {
    auto sphere = std::make_shared<std::vector<Triangle>>(make_icosphere(2).triangles());
    std::shared_ptr<Accel> structure = make_accel("bvh8");
    structure->build({*sphere, {}}, build_options(TriangleTest::Watertight));
    for (const float distance : {4.0f, 400.0f}) {
        InstancedScene scene;
        const std::uint32_t object = scene.add_object(structure);
        const Transform shared =
            Transform::translation({1.0f, 2.0f, 3.0f}) * Transform::rotation({0, 1, 1}, 0.7f);
        // Three instances, the middle one alone elsewhere, the first and last identical.
        const std::uint32_t first = scene.add_instance(object, shared);
        scene.add_instance(object, Transform::translation({50.0f, 0.0f, 0.0f}));
        const std::uint32_t last = scene.add_instance(object, shared);
        scene.commit();
        // Rays from around the shared instance aimed at points near its centre.
        const std::vector<Ray> rays = rays_at_centre({1.0f, 2.0f, 3.0f}, distance, 1000, 9);
        std::vector<InstanceHit> hits(rays.size());
        scene.intersect(rays, hits);
        std::size_t tied = 0;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            const InstanceHit& hit = hits[i];
            InstanceHit alone;
            scene.intersect({&rays[i], 1}, {&alone, 1});
            EXPECT_EQ(alone.instance, hit.instance) << distance;
            if (!hit.hit() || hit.instance == 1) continue;
            ++tied;
            EXPECT_EQ(hit.instance, static_cast<std::int32_t>(first)) << distance;
        }
        EXPECT_GT(tied, 900u) << distance;
        // With the first removed, the last answers the same rays.
        scene.remove_instance(first);
        scene.commit();
        std::vector<InstanceHit> after(rays.size());
        scene.intersect(rays, after);
        for (std::size_t i = 0; i < rays.size(); ++i) {
            if (!hits[i].hit() || hits[i].instance == 1) continue;
            EXPECT_EQ(after[i].instance, static_cast<std::int32_t>(last)) << distance;
            EXPECT_EQ(after[i].t, hits[i].t) << distance;
            EXPECT_EQ(after[i].prim, hits[i].prim) << distance;
        }
    }
}

// Two instances with the same surface, the one with the larger id inside a larger box, so that every walk
// visits it first: from origins far from both, which the walk moves near each object, the hit it finds
// first rounds to a t that the other's must then reach again, and the smaller id must still win the tie.
TEST(InstancedScene, TiesGoToTheSmallerInstanceIdVisitedSecond) {
    const std::vector<Triangle> sphere = make_icosphere(2).triangles();
    // The sphere and, at the corners of a box ten times its size, tiny triangles no ray below comes near.
    std::vector<Triangle> boxed = sphere;
    for (const float x : {-10.0f, 10.0f}) {
        for (const float y : {-10.0f, 10.0f}) {
            for (const float z : {-10.0f, 10.0f}) {
                const Vec3f corner(x, y, z);
                boxed.push_back(
                    {corner, corner + Vec3f(1e-3f, 0.0f, 0.0f), corner + Vec3f(0.0f, 1e-3f, 0.0f)});
            }
        }
    }
    InstancedScene scene;
    scene.add_object(mesh_of(sphere), "bvh8", build_options(TriangleTest::Watertight));
    scene.add_object(mesh_of(boxed), "bvh8", build_options(TriangleTest::Watertight));
    const Transform shared =
        Transform::translation({1.0f, 2.0f, 3.0f}) * Transform::rotation({0, 1, 1}, 0.7f);
    const std::uint32_t first = scene.add_instance(0, shared);
    scene.add_instance(1, shared);
    // A third far away, so that the scene's box holds the origins (which the scene's own ray conditioning
    // would move otherwise, near both instances at once).
    scene.add_instance(0, Transform::translation({4000.0f, 0.0f, 0.0f}));
    scene.commit();
    const std::vector<Ray> rays = rays_at_centre({1.0f, 2.0f, 3.0f}, 1000.0f, 2000, 10);
    std::vector<InstanceHit> hits(rays.size());
    scene.intersect(rays, hits);
    std::size_t hit_count = 0, lost = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        InstanceHit alone;
        scene.intersect({&rays[i], 1}, {&alone, 1});
        if (!hits[i].hit()) continue;
        ++hit_count;
        lost += hits[i].instance == static_cast<std::int32_t>(first) &&
                        alone.instance == static_cast<std::int32_t>(first)
                    ? 0
                    : 1;
    }
    EXPECT_GT(hit_count, 1900u);
    EXPECT_EQ(lost, 0u);
}

}  // namespace
}  // namespace lancer::testing
