// Two-level scenes (lancer/instances.hpp) against the same scene flattened in double precision, the
// watertight test inside instances, rigid motion (the objects untouched, the answers a fresh build's), the
// tie rule and bad transforms. The bound every hit is held to: docs/numerical-contract.md, "Instances".
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "lancer/generate.hpp"
#include "lancer/instances.hpp"
#include "lancer/vec3d.hpp"
#include "support/ray_sets.hpp"

namespace lancer {
namespace {

using testing::RaySet;

// The contract's bound on a hit's t, in the object's frame (where t is the same): the object ray rounds to
// 2^-24 of its coordinates and the kernel to a few 2^-24 of the distance to the triangle, which moves the
// hit along the ray by that distance over the cosine between the ray and the triangle.
constexpr double kBoundFactor = 0x1p-19;
// A hit's barycentrics may lie this far outside [0, 1] (a hit within the kernels' tolerance of an edge), and
// an exact hit at least this far inside every edge must be found; more where the bound on t moves the hit
// point by more (barycentric_bound).
constexpr double kEdgeMargin = 1e-3;

struct Affine {
    double a[3][3];
    double b[3];

    explicit Affine(const Transform& t) {
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c)
                a[r][c] = t.m[r][c];
            b[r] = t.m[r][3];
        }
    }
    [[nodiscard]] Vec3d point(const Vec3f& p) const { return apply(Vec3d(p), true); }
    [[nodiscard]] Vec3d apply(const Vec3d& p, bool translate) const {
        const double x[3] = {p.x, p.y, p.z};
        double out[3];
        for (int r = 0; r < 3; ++r)
            out[r] = a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2] + (translate ? b[r] : 0.0);
        return {out[0], out[1], out[2]};
    }
};

double length(const Vec3d& v) {
    return std::sqrt(dot(v, v));
}

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

// The scene flattened: each instance's triangles mapped to the world in double.
struct FlatScene {
    struct Placed {
        std::int32_t instance;
        std::int32_t prim;
        Vec3d v0, v1, v2;
    };
    std::vector<Placed> triangles;
    std::vector<Affine> transforms;    // by instance
    std::vector<double> object_sizes;  // by instance: the object's largest vertex norm
};

struct Fixture {
    std::vector<std::vector<Triangle>> object_triangles;
    std::vector<Transform> transforms;
    std::vector<std::uint32_t> objects;  // of each instance
};

// A few objects placed by random rotations, non-uniform scales and translations, no two alike, overlapping.
Fixture random_fixture(std::uint32_t seed, int instances) {
    Fixture fixture;
    fixture.object_triangles.push_back(make_icosphere(2).triangles());
    fixture.object_triangles.push_back(make_torus_knot(48, 6).triangles());
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), scale(0.3f, 2.0f), angle(0.0f, 6.2831853f);
    for (int i = 0; i < instances; ++i) {
        const Vec3f axis(unit(rng), unit(rng), unit(rng) + 1.5f);
        fixture.transforms.push_back(
            Transform::translation({6.0f * unit(rng), 6.0f * unit(rng), 6.0f * unit(rng)}) *
            Transform::rotation(axis, angle(rng)) * Transform::scaling({scale(rng), scale(rng), scale(rng)}));
        fixture.objects.push_back(static_cast<std::uint32_t>(i % 2));
    }
    return fixture;
}

FlatScene flatten(const Fixture& fixture) {
    FlatScene flat;
    for (std::size_t i = 0; i < fixture.transforms.size(); ++i) {
        const Affine affine(fixture.transforms[i]);
        flat.transforms.push_back(affine);
        const auto& triangles = fixture.object_triangles[fixture.objects[i]];
        double object_size = 0.0;
        for (const Triangle& t : triangles)
            object_size =
                std::max({object_size, length(Vec3d(t.v0)), length(Vec3d(t.v1)), length(Vec3d(t.v2))});
        flat.object_sizes.push_back(object_size);
        for (std::size_t prim = 0; prim < triangles.size(); ++prim) {
            const Triangle& t = triangles[prim];
            flat.triangles.push_back({static_cast<std::int32_t>(i), static_cast<std::int32_t>(prim),
                                      affine.point(t.v0), affine.point(t.v1), affine.point(t.v2)});
        }
    }
    return flat;
}

// The fixture's instances under ids 0, 1, ..., the ids in `skipped` passed over (skip_instance_id), their
// instances left out.
InstancedScene make_scene(const Fixture& fixture, std::string_view accel, TriangleTest test,
                          const std::vector<std::uint32_t>& skipped = {}) {
    InstancedScene scene;
    for (const auto& triangles : fixture.object_triangles) {
        TriangleMesh mesh;
        for (const Triangle& t : triangles) {
            for (const Vec3f& p : {t.v0, t.v1, t.v2}) {
                mesh.indices.push_back(static_cast<std::uint32_t>(mesh.positions.size()));
                mesh.positions.push_back(p);
            }
        }
        scene.add_object(mesh, accel, build_options(test));
    }
    for (std::uint32_t i = 0; i < fixture.transforms.size(); ++i) {
        if (std::ranges::find(skipped, i) != skipped.end())
            scene.skip_instance_id();
        else
            scene.add_instance(fixture.objects[i], fixture.transforms[i]);
    }
    scene.commit();
    return scene;
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

// Every answer of `scene` held to the flattened scene: a reported hit lies on its triangle (barycentrics
// within kEdgeMargin) at the exact t within the bound, and no exact hit well inside a triangle lies nearer
// than it by more than the bound (nor is missed).
Verdict check_against_flat(const InstancedScene& scene, const Fixture& fixture, const FlatScene& flat,
                           std::span<const Ray> rays) {
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
        // The nearest exact hit well inside a triangle, not grazing, well inside [tnear, tfar].
        double nearest = std::numeric_limits<double>::infinity(), nearest_bound = 0.0;
        for (const FlatScene::Placed& placed : flat.triangles) {
            PlaneHit exact;
            if (!plane_hit(o, d, placed.v0, placed.v1, placed.v2, exact)) continue;
            // A hit beyond the float range is none (docs/numerical-contract.md, "Ray conditioning").
            if (exact.cosine < 1e-3 || exact.t > std::numeric_limits<float>::max()) continue;
            const double bound = t_bound(flat, placed, ray, exact.t, exact.cosine);
            if (exact.edge_distance() < barycentric_bound(placed, bound * length(d))) continue;
            if (exact.t < double(ray.tnear) + bound || exact.t > double(ray.tfar) - bound) continue;
            if (exact.t < nearest) nearest = exact.t, nearest_bound = bound;
        }
        if (nearest == std::numeric_limits<double>::infinity()) continue;
        ++verdict.checked_misses;
        if (!hit.hit()) {
            verdict.fail(i, "missed an exact hit at t = " + std::to_string(nearest));
        } else if (hit.t > nearest + nearest_bound) {
            verdict.fail(i, "hit at t = " + std::to_string(hit.t) + " behind an exact hit at " +
                                std::to_string(nearest));
        }
    }
    return verdict;
}

// Rays that start inside instances (at their centres), and rays grazing triangles: from a point of a
// triangle's plane near it, along the plane with a small normal component.
RaySet inside_and_grazing_rays(const Fixture& fixture, const FlatScene& flat, std::size_t count,
                               std::uint32_t seed) {
    RaySet set{"inside and grazing", {}};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    for (std::size_t i = 0; i < count; ++i) {
        if (i % 2 == 0) {
            const Transform& t = fixture.transforms[i / 2 % fixture.transforms.size()];
            const Vec3f centre(t.m[0][3], t.m[1][3], t.m[2][3]);
            set.rays.push_back({centre, {unit(rng), unit(rng), unit(rng)}, 0.0f, kInfinity});
            continue;
        }
        const FlatScene::Placed& placed = flat.triangles[rng() % flat.triangles.size()];
        const Vec3d e1 = placed.v1 - placed.v0, e2 = placed.v2 - placed.v0;
        const Vec3d n = normalize(cross(e1, e2));
        const Vec3d target = placed.v0 + 0.3 * e1 + 0.3 * e2;
        const Vec3d along = normalize(e1);
        const double tilt = 1e-3 * unit(rng);
        const Vec3d direction = along + tilt * n;
        const Vec3d origin = target - 2.0 * direction;
        set.rays.push_back(
            {{static_cast<float>(origin.x), static_cast<float>(origin.y), static_cast<float>(origin.z)},
             {static_cast<float>(direction.x), static_cast<float>(direction.y),
              static_cast<float>(direction.z)},
             0.0f,
             kInfinity});
    }
    return set;
}

struct Case {
    std::string_view accel;
    TriangleTest test;
};

class InstancedOracle : public ::testing::TestWithParam<Case> {};

// Every object structure, both triangle tests: random rays, axis-parallel and zero-component rays, clipped
// intervals, NaN and other invalid rays, rays from inside instances and grazing rays, all against the scene
// flattened in double.
TEST_P(InstancedOracle, EveryHitWithinTheBoundOfTheFlattenedScene) {
    const Fixture fixture = random_fixture(5, 24);
    const FlatScene flat = flatten(fixture);
    const InstancedScene scene = make_scene(fixture, GetParam().accel, GetParam().test);
    const Box3f bounds = scene.bounds();
    std::vector<RaySet> sets = {testing::random_rays(bounds, 1500, 1),
                                testing::axis_parallel_rays(bounds, 600, 2),
                                testing::clipped_rays(bounds, 600, 3), testing::hostile_rays(bounds),
                                inside_and_grazing_rays(fixture, flat, 600, 4)};
    for (const RaySet& set : sets) {
        const Verdict verdict = check_against_flat(scene, fixture, flat, set.rays);
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
                         [](const auto& param_info) {
                             return std::string(param_info.param.accel) +
                                    (param_info.param.test == TriangleTest::Watertight ? "_watertight"
                                                                                       : "_moller");
                         });

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

// At equal t the smaller instance id wins: two instances of one object under the same transform, added in
// either order of the boxes' walk.
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

// From origins near the instances and from far ones, which the walk moves near each object before tracing it
// (docs/numerical-contract.md, "Far origins"), in a batch (whose rays walk the top level together) and ray by
// ray.
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
    for (const std::vector<Triangle>* triangles :
         {&sphere, static_cast<const std::vector<Triangle>*>(&boxed)}) {
        TriangleMesh mesh;
        for (const Triangle& t : *triangles) {
            for (const Vec3f& p : {t.v0, t.v1, t.v2}) {
                mesh.indices.push_back(static_cast<std::uint32_t>(mesh.positions.size()));
                mesh.positions.push_back(p);
            }
        }
        scene.add_object(mesh, "bvh8", build_options(TriangleTest::Watertight));
    }
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

// The same answer bit for bit: t, primitive, barycentrics, instance and object.
bool same_hit(const InstanceHit& a, const InstanceHit& b) {
    const auto bits = [](float x) { return std::bit_cast<std::uint32_t>(x); };
    return bits(a.t) == bits(b.t) && a.prim == b.prim && bits(a.u) == bits(b.u) && bits(a.v) == bits(b.v) &&
           a.instance == b.instance && a.object == b.object;
}

bool same_hits(const std::vector<InstanceHit>& a, const std::vector<InstanceHit>& b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), same_hit);
}

// Moving, adding and removing instances rebuilds or refits the top level only: the objects are the same
// structures, built once (their build time and address unchanged), and the answers equal those of a scene
// built afresh with the final instances, bit for bit.
TEST(InstancedScene, RigidMotionUpdatesTheTopLevelOnlyAndAnswersAsAFreshBuild) {
    Fixture fixture = random_fixture(21, 40);
    auto triangles0 = std::make_shared<std::vector<Triangle>>(fixture.object_triangles[0]);
    auto triangles1 = std::make_shared<std::vector<Triangle>>(fixture.object_triangles[1]);
    std::shared_ptr<Accel> object0 = make_accel("bvh8"), object1 = make_accel("bvh8_packet");
    object0->build({*triangles0, {}}, build_options(TriangleTest::Watertight));
    object1->build({*triangles1, {}}, build_options(TriangleTest::Watertight));
    const double build0 = object0->stats().build_ms, build1 = object1->stats().build_ms;
    const std::size_t bytes0 = object0->memory_bytes(), bytes1 = object1->memory_bytes();

    BuildOptions top_level;
    set_build_option(top_level, "bvh.refit_threshold=1e9");  // refit whatever the degradation
    InstancedScene scene(top_level);
    scene.add_object(object0), scene.add_object(object1);
    for (std::size_t i = 0; i < fixture.transforms.size(); ++i)
        scene.add_instance(fixture.objects[i], fixture.transforms[i]);
    EXPECT_EQ(scene.commit().method, UpdateMethod::Rebuild);

    std::mt19937 rng(8);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    // A rigid step of every instance: refitted.
    for (std::size_t i = 0; i < fixture.transforms.size(); ++i) {
        fixture.transforms[i] = Transform::translation({unit(rng), unit(rng), unit(rng)}) *
                                fixture.transforms[i] * Transform::rotation({0, 0, 1}, 0.3f * unit(rng));
        scene.set_transform(static_cast<std::uint32_t>(i), fixture.transforms[i]);
    }
    const std::vector<Ray> rays = testing::random_rays(scene.bounds(), 3000, 12).rays;
    std::vector<InstanceHit> hits(rays.size()), fresh_hits(rays.size());
    EXPECT_THROW(scene.intersect(rays, hits), std::logic_error);
    const UpdateReport moved = scene.commit();
    EXPECT_EQ(moved.method, UpdateMethod::Refit);
    EXPECT_GE(moved.sah_ratio, 0.0);

    // A fresh scene with the final instances, and the same ids (removed ones added, then removed).
    const auto fresh = [&](const std::vector<std::uint32_t>& removed) {
        InstancedScene built;
        built.add_object(object0), built.add_object(object1);
        for (std::size_t i = 0; i < fixture.transforms.size(); ++i)
            built.add_instance(fixture.objects[i], fixture.transforms[i]);
        for (const std::uint32_t id : removed)
            built.remove_instance(id);
        built.commit();
        return built;
    };
    const auto check_fresh = [&](const std::vector<std::uint32_t>& removed) {
        scene.intersect(rays, hits);
        fresh(removed).intersect(rays, fresh_hits);
        EXPECT_TRUE(same_hits(hits, fresh_hits));
        EXPECT_GT(std::count_if(hits.begin(), hits.end(), [](const InstanceHit& h) { return h.hit(); }), 300);
    };
    check_fresh({});

    // Removed and added: rebuilt.
    scene.remove_instance(3), scene.remove_instance(7);
    fixture.transforms.push_back(Transform::translation({0.5f, 0.5f, 0.5f}) *
                                 Transform::scaling({3.0f, 1.0f, 2.0f}));
    fixture.objects.push_back(0);
    EXPECT_EQ(scene.add_instance(0, fixture.transforms.back()), fixture.transforms.size() - 1);
    EXPECT_EQ(scene.commit().method, UpdateMethod::Rebuild);
    EXPECT_EQ(scene.instance_count(), fixture.transforms.size() - 2);
    check_fresh({3, 7});

    // The objects: the structures handed in, never rebuilt.
    EXPECT_EQ(&scene.object(0), object0.get());
    EXPECT_EQ(&scene.object(1), object1.get());
    EXPECT_EQ(object0->stats().build_ms, build0);
    EXPECT_EQ(object1->stats().build_ms, build1);
    EXPECT_EQ(object0->memory_bytes(), bytes0);
    EXPECT_EQ(object1->memory_bytes(), bytes1);
}

// An id passed over (what restores a pickled scene's ids) is a removed instance's: the scene answers, counts
// and weighs as the one that added and removed it, refuses it as a removed id, and gives the next id after
// it.
TEST(InstancedScene, SkippedIdsAreRemovedOnes) {
    const Fixture fixture = random_fixture(17, 12);
    const std::vector<std::uint32_t> removed = {0, 5, 11};  // the first, one inside, the last
    InstancedScene added = make_scene(fixture, "bvh8", TriangleTest::Watertight);
    for (const std::uint32_t id : removed)
        added.remove_instance(id);
    added.commit();
    InstancedScene skipped = make_scene(fixture, "bvh8", TriangleTest::Watertight, removed);
    EXPECT_EQ(skipped.instance_count(), added.instance_count());
    EXPECT_EQ(skipped.instanced_primitive_count(), added.instanced_primitive_count());
    EXPECT_EQ(skipped.memory_bytes(), added.memory_bytes());
    EXPECT_EQ(skipped.bounds().lo, added.bounds().lo);
    EXPECT_EQ(skipped.bounds().hi, added.bounds().hi);
    for (std::uint32_t id = 0; id < fixture.transforms.size(); ++id) {
        EXPECT_EQ(skipped.contains(id), added.contains(id)) << id;
        if (skipped.contains(id)) {
            EXPECT_EQ(skipped.transform(id), added.transform(id)) << id;
        }
    }
    EXPECT_THROW(skipped.remove_instance(5), std::invalid_argument);
    EXPECT_THROW(skipped.set_transform(5, Transform{}), std::invalid_argument);
    EXPECT_THROW(static_cast<void>(skipped.transform(11)), std::invalid_argument);

    const std::vector<Ray> rays = testing::random_rays(added.bounds(), 4000, 18).rays;
    std::vector<InstanceHit> expected(rays.size()), hits(rays.size());
    added.intersect(rays, expected);
    skipped.intersect(rays, hits);
    EXPECT_TRUE(same_hits(hits, expected));
    EXPECT_GT(std::count_if(hits.begin(), hits.end(), [](const InstanceHit& h) { return h.hit(); }), 400);
    std::vector<std::uint8_t> expected_occluded(rays.size()), occluded(rays.size());
    added.occluded(rays, expected_occluded);
    skipped.occluded(rays, occluded);
    EXPECT_EQ(occluded, expected_occluded);

    EXPECT_EQ(skipped.skip_instance_id(), 12u);
    EXPECT_EQ(skipped.add_instance(0, Transform{}), 13u);
}

// The SAH watch of the refit (docs/accel/refit.md) decides for the top level: a small step refits, a
// scramble of the instances' places degrades the refitted tree past bvh.refit_threshold and rebuilds it.
TEST(InstancedScene, TheTopLevelRebuildsOnceItsRefittedCostDegrades) {
    Fixture fixture = random_fixture(3, 200);
    InstancedScene scene = make_scene(fixture, "bvh8", TriangleTest::Watertight);
    const std::size_t n = fixture.transforms.size();
    for (std::size_t i = 0; i < n; ++i)
        scene.set_transform(static_cast<std::uint32_t>(i),
                            Transform::translation({1e-3f, 0.0f, 0.0f}) * fixture.transforms[i]);
    const UpdateReport small = scene.commit();
    EXPECT_EQ(small.method, UpdateMethod::Refit);
    EXPECT_LT(small.sah_ratio, 1.01);
    // Each instance takes the place of one far across the scene.
    for (std::size_t i = 0; i < n; ++i) {
        Transform moved = fixture.transforms[i];
        const Transform& other = fixture.transforms[(i + n / 2) % n];
        for (int r = 0; r < 3; ++r)
            moved.m[r][3] = other.m[r][3];
        scene.set_transform(static_cast<std::uint32_t>(i), moved);
    }
    EXPECT_EQ(scene.commit().method, UpdateMethod::Rebuild);
}

// A transform with a NaN or infinite entry, a singular or too ill-conditioned one, or one that leaves the
// coordinate domain, an unknown object or instance: std::invalid_argument naming the instance, the scene left
// as it was.
TEST(InstancedScene, BadTransformsAndIdsAreRefusedNamingTheInstance) {
    InstancedScene scene;
    TriangleMesh mesh = make_icosphere(1);
    const std::uint32_t object = scene.add_object(mesh, "bvh8", build_options(TriangleTest::Watertight));
    scene.add_instance(object, Transform{});
    const auto message = [&](auto&& call) {
        try {
            call();
        } catch (const std::invalid_argument& error) {
            return std::string(error.what());
        }
        return std::string("no exception");
    };
    Transform nan;
    nan.m[1][2] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_NE(message([&] { scene.add_instance(object, nan); }).find("instance 1's transform has a NaN"),
              std::string::npos);
    Transform singular = Transform::scaling({1.0f, 0.0f, 1.0f});
    EXPECT_NE(message([&] { scene.set_transform(0, singular); }).find("instance 0's transform is singular"),
              std::string::npos);
    const Transform flat = Transform::scaling({0x1p15f, 0x1p-15f, 1.0f});  // condition number 2^30
    EXPECT_NE(message([&] { scene.set_transform(0, flat); }).find("ill-conditioned"), std::string::npos);
    EXPECT_NE(message([&] {
                  scene.add_instance(object, Transform::translation({0x1p61f, 0.0f, 0.0f}));
              }).find("coordinate domain"),
              std::string::npos);
    EXPECT_NE(message([&] { scene.add_instance(7, Transform{}); }).find("names object 7"), std::string::npos);
    EXPECT_NE(message([&] { scene.remove_instance(5); }).find("no instance 5"), std::string::npos);
    EXPECT_NE(message([&] { scene.add_object(nullptr); }).find("null"), std::string::npos);
    EXPECT_NE(message([&] { scene.add_object(make_accel("bvh8")); }).find("unbuilt"), std::string::npos);
    // Nothing was changed by the refusals: the one instance, committed, answers as before.
    EXPECT_EQ(scene.instance_count(), 1u);
    EXPECT_EQ(scene.transform(0), Transform{});
    scene.commit();
    const Ray ray{{0.0f, 0.0f, -5.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, kInfinity};
    InstanceHit hit;
    scene.intersect({&ray, 1}, {&hit, 1});
    EXPECT_TRUE(hit.hit());
    EXPECT_EQ(hit.instance, 0);
    EXPECT_NEAR(hit.t, 4.0f, 0.1f);
    // A refused instance took no id.
    EXPECT_EQ(scene.add_instance(object, Transform::translation({3.0f, 0.0f, 0.0f})), 1u);
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
        std::size_t mismatches = 0, hit_count = 0;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            const InstanceHit &a = expected[i], &b = hits[i];
            hit_count += a.hit() ? 1 : 0;
            bool same = a.hit() == b.hit() && (occluded[i] != 0) == a.hit();
            if (same && a.hit()) {
                const bool same_triangle = a.instance == b.instance && a.prim == b.prim;
                same = std::fabs(a.t - b.t) <= 1e-5f * std::fabs(a.t) &&
                       (same_triangle ? std::fabs(a.u - b.u) <= 1e-4f && std::fabs(a.v - b.v) <= 1e-4f
                                      : a.t == b.t);
            }
            mismatches += same ? 0 : 1;
        }
        EXPECT_EQ(mismatches, 0u) << name;
        EXPECT_GT(hit_count, rays.size() / 10) << name;
    }
    EXPECT_GE(structures, 10u);
}

// Rays from far beyond the scene aimed at it on a grid, 8x8 tiles of them consecutive as the bench's primary
// rays: coherent rays whose origins the walk moves near each object (each its own way).
std::vector<Ray> far_view_rays(const Box3f& bounds, int size) {
    const Vec3f centre = bounds.center();
    const float side = max_component(bounds.extent());
    const Vec3f eye = centre + Vec3f(0.3f, 0.2f, 60.0f) * side;
    std::vector<Ray> rays;
    for (int tile_y = 0; tile_y < size; tile_y += 8) {
        for (int tile_x = 0; tile_x < size; tile_x += 8) {
            for (int y = tile_y; y < tile_y + 8; ++y) {
                for (int x = tile_x; x < tile_x + 8; ++x) {
                    const Vec3f target = centre + side * Vec3f((float(x) + 0.5f) / float(size) - 0.5f,
                                                               (float(y) + 0.5f) / float(size) - 0.5f, 0.0f);
                    rays.push_back({eye, target - eye, 0.0f, kInfinity});
                }
            }
        }
    }
    return rays;
}

// Random rays that start behind their origin (tnear < 0), some with a finite tfar.
std::vector<Ray> backward_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed) {
    std::vector<Ray> rays = testing::random_rays(bounds, count, seed).rays;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const float diagonal = length(bounds.extent());
    for (std::size_t i = 0; i < rays.size(); ++i) {
        rays[i].tnear = -diagonal * unit(rng);
        if (i % 3 == 0) rays[i].tfar = diagonal * unit(rng);
    }
    return rays;
}

class InstancedBatches : public ::testing::TestWithParam<Case> {};

// A batch answers each ray as a call with that ray alone: its closest hit (t, primitive, barycentrics,
// instance, object) and its occlusion, bit for bit, for batches of every size (15; 64, the packets' and a
// bench tile's; 65; 4,096, intersect_parallel's tasks), whatever a batch's walk shares between its rays
// (groups of 64 rays walking the top level together were measured: docs/accel/instances.md). The scene has
// identical instances (ties), the rays every kind the oracle test traces and more: coherent rays from near
// and from far, rays behind their origins, random and grazing ones, invalid ones among them.
TEST_P(InstancedBatches, EveryRayAnswersAsItsOwnWalk) {
    Fixture fixture = random_fixture(41, 30);
    for (std::size_t i = 0; i < 6; ++i) {
        fixture.transforms.push_back(fixture.transforms[3 * i]);
        fixture.objects.push_back(fixture.objects[3 * i]);
    }
    const FlatScene flat = flatten(fixture);
    const InstancedScene scene = make_scene(fixture, GetParam().accel, GetParam().test);
    const Box3f bounds = scene.bounds();
    std::vector<Ray> rays = testing::canonical_view_rays(bounds, 48).rays;
    for (const std::vector<Ray>& set :
         {far_view_rays(bounds, 48), testing::random_rays(bounds, 1500, 42).rays,
          testing::axis_parallel_rays(bounds, 300, 43).rays, testing::clipped_rays(bounds, 300, 44).rays,
          testing::hostile_rays(bounds).rays, inside_and_grazing_rays(fixture, flat, 600, 45).rays,
          backward_rays(bounds, 300, 46)})
        rays.insert(rays.end(), set.begin(), set.end());
    std::vector<InstanceHit> alone(rays.size());
    std::vector<std::uint8_t> occluded_alone(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) {
        scene.intersect({&rays[i], 1}, {&alone[i], 1});
        scene.occluded({&rays[i], 1}, {&occluded_alone[i], 1});
    }
    std::size_t hit_count = 0;
    for (const InstanceHit& hit : alone)
        hit_count += hit.hit() ? 1 : 0;
    EXPECT_GT(hit_count, rays.size() / 4);
    for (const std::size_t batch : {std::size_t{15}, std::size_t{64}, std::size_t{65}, std::size_t{4096}}) {
        std::vector<InstanceHit> hits(rays.size());
        std::vector<std::uint8_t> occluded(rays.size());
        for (std::size_t first = 0; first < rays.size(); first += batch) {
            const std::size_t count = std::min(batch, rays.size() - first);
            scene.intersect(std::span(rays).subspan(first, count), std::span(hits).subspan(first, count));
            scene.occluded(std::span(rays).subspan(first, count), std::span(occluded).subspan(first, count));
        }
        std::size_t differ = 0;
        for (std::size_t i = 0; i < rays.size(); ++i)
            differ += same_hit(alone[i], hits[i]) ? 0 : 1;
        EXPECT_EQ(differ, 0u) << "batches of " << batch;
        EXPECT_EQ(occluded, occluded_alone) << "batches of " << batch;
    }
}

INSTANTIATE_TEST_SUITE_P(PacketAndSingleRayObjects, InstancedBatches,
                         ::testing::Values(Case{"bvh8", TriangleTest::Watertight},
                                           Case{"bvh8", TriangleTest::MollerTrumbore},
                                           Case{"bvh8_packet", TriangleTest::Watertight},
                                           Case{"bvh8_packet", TriangleTest::MollerTrumbore}),
                         [](const ::testing::TestParamInfo<Case>& param_info) {
                             return std::string(param_info.param.accel) +
                                    (param_info.param.test == TriangleTest::Watertight ? "_watertight"
                                                                                       : "_moller");
                         });

// intersect_parallel and occluded_parallel answer as one call.
TEST(InstancedScene, ParallelBatchesAnswerAsOneCall) {
    const Fixture fixture = random_fixture(13, 30);
    const InstancedScene scene = make_scene(fixture, "bvh8_packet", TriangleTest::Watertight);
    const std::vector<Ray> rays = testing::random_rays(scene.bounds(), 20000, 14).rays;
    std::vector<InstanceHit> one(rays.size()), parallel(rays.size());
    scene.intersect(rays, one);
    intersect_parallel(scene, rays, parallel, 2);
    EXPECT_TRUE(same_hits(one, parallel));
    std::vector<std::uint8_t> occluded_one(rays.size()), occluded_parallel_(rays.size());
    scene.occluded(rays, occluded_one);
    occluded_parallel(scene, rays, occluded_parallel_, 2);
    EXPECT_EQ(occluded_one, occluded_parallel_);
    TraversalCounters counters;
    scene.intersect(rays, one, &counters);
    EXPECT_EQ(counters.rays, rays.size());
    EXPECT_GT(counters.prims_tested, 0u);
}

}  // namespace
}  // namespace lancer
