// Two-level scenes (lancer/instances.hpp) as a structure: rigid motion (the objects untouched, the answers a
// fresh build's), skipped ids, the top level's rebuild, bad transforms, batches answering as each ray alone
// and the objects' one-ray walks answering as their batch calls. Every structure as an object:
// object_structures_test.cpp; the tests a visit starts with: visit_test.cpp; the numerical contract:
// instanced_contract_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "instanced_fixture.hpp"
#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "lancer/instances.hpp"
#include "support/ray_sets.hpp"

namespace lancer::testing {
namespace {

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

// An instance's world box is the box of its object's 26-sided polytope mapped, not of its object box's
// corners: a sphere turned by 45 degrees keeps about its own box (its box's corners would widen it by
// sqrt(2) or more), and every vertex of the turned sphere, and every hit, stays inside it. The same for a
// sphere of radius 2^22, which its structure holds scaled by a power of two (Accel::built_geometry), placed
// at radius 1.
TEST(InstancedScene, AnInstanceBoxFollowsItsObjectsShapeUnderRotation) {
    const Transform turn =
        Transform::translation({5.0f, -3.0f, 2.0f}) * Transform::rotation({1.0f, 1.0f, 0.0f}, 0.785398f);
    for (const float radius : {1.0f, 0x1p22f}) {
        const TriangleMesh sphere = make_icosphere(3, {0, 0, 0}, radius);
        const Transform place = turn * Transform::scaling(Vec3f(1.0f / radius));
        InstancedScene scene;
        const std::uint32_t object =
            scene.add_object(sphere, "bvh8", build_options(TriangleTest::Watertight));
        scene.add_instance(object, place);
        scene.commit();
        const Box3f& box = scene.bounds();
        for (int axis = 0; axis < 3; ++axis)  // the corners' box: 3 to 3.4 wide here
            EXPECT_LT(box.extent()[axis], 2.0f * 1.15f) << "radius " << radius << ", axis " << axis;
        for (const Vec3f& vertex : sphere.positions) {
            const Vec3f moved = place.point(vertex);
            for (int axis = 0; axis < 3; ++axis) {
                ASSERT_LE(box.lo[axis], moved[axis]) << radius;
                ASSERT_GE(box.hi[axis], moved[axis]) << radius;
            }
        }
        // Rays from outside the box towards the centre, and from the centre towards each vertex (a leak
        // would be a miss): every one hits the sphere.
        const Vec3f centre = place.point({0.0f, 0.0f, 0.0f});
        std::mt19937 rng(5);
        std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
        std::vector<Ray> rays;
        for (const Vec3f& vertex : sphere.positions) {
            const Vec3f outside = centre + 3.0f * normalize(Vec3f(unit(rng), unit(rng), unit(rng)));
            rays.push_back({outside, centre - outside, 0.0f, kInfinity});
            rays.push_back({centre, place.point(vertex) - centre, 0.0f, kInfinity});
        }
        std::vector<InstanceHit> hits(rays.size());
        scene.intersect(rays, hits);
        for (std::size_t i = 0; i < rays.size(); ++i)
            ASSERT_TRUE(hits[i].hit()) << "radius " << radius << ": ray " << i << " misses";
    }
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

// Rays on a size x size grid in 8x8 tiles, each tile's 64 rays consecutive, as the bench's primary rays
// (the packets the top level walks together: InstancedScene::Walk::walk_packet). make(u, v) gives the ray
// of the grid point (u, v) in (-0.5, 0.5)^2; every `invalid_every`-th ray (0: none) then gets a NaN
// direction, so that a packet holds invalid rays among valid ones.
template <class Make>
std::vector<Ray> tiled_rays(int size, int invalid_every, Make&& make) {
    std::vector<Ray> rays;
    for (int tile_y = 0; tile_y < size; tile_y += 8) {
        for (int tile_x = 0; tile_x < size; tile_x += 8) {
            for (int y = tile_y; y < tile_y + 8; ++y) {
                for (int x = tile_x; x < tile_x + 8; ++x) {
                    Ray ray =
                        make((float(x) + 0.5f) / float(size) - 0.5f, (float(y) + 0.5f) / float(size) - 0.5f);
                    if (invalid_every > 0 && rays.size() % static_cast<std::size_t>(invalid_every) == 0)
                        ray.direction.y = std::numeric_limits<float>::quiet_NaN();
                    rays.push_back(ray);
                }
            }
        }
    }
    return rays;
}

// Rays from far beyond the scene aimed at it: coherent rays whose origins the walk moves near each object
// (each its own way).
std::vector<Ray> far_view_rays(const Box3f& bounds, int size) {
    const Vec3f centre = bounds.center();
    const float side = max_component(bounds.extent());
    const Vec3f eye = centre + Vec3f(0.3f, 0.2f, 60.0f) * side;
    return tiled_rays(size, 0, [&](float u, float v) {
        return Ray{eye, centre + side * Vec3f(u, v, 0.0f) - eye, 0.0f, kInfinity};
    });
}

// Rays from an eye within the scene's reach (not moved by ray conditioning) towards a plane through the
// scene's centre, or half a side below it when the eye is inside the scene (`eye_z`: the eye's height over
// the centre, in the scene's largest side). `tnear` and `tfar` are each ray's interval (t = 1 at the plane).
std::vector<Ray> tiled_view_rays(const Box3f& bounds, int size, float eye_z, float tnear, float tfar,
                                 int invalid_every) {
    const Vec3f centre = bounds.center();
    const float side = max_component(bounds.extent());
    const Vec3f eye = centre + Vec3f(0.3f, 0.2f, eye_z) * side;
    const float plane_z = eye_z > 0.5f ? 0.0f : -0.5f;
    return tiled_rays(size, invalid_every, [&](float u, float v) {
        return Ray{eye, centre + side * Vec3f(u, v, plane_z) - eye, tnear, tfar};
    });
}

// Shadow rays towards one point light above the scene, as the shadow view makes them (direction L - o,
// [0, 1 - 1e-4]), from points across the scene's middle: their origins lie far apart and their ends
// together, so a tile's occlusion rays walk the top level culled from their ends.
std::vector<Ray> shadow_rays_to_a_light(const Box3f& bounds, int size, int invalid_every) {
    const Vec3f centre = bounds.center();
    const float side = max_component(bounds.extent());
    const Vec3f light = centre + Vec3f(0.5f, 2.0f, 1.5f) * side;
    return tiled_rays(size, invalid_every, [&](float u, float v) {
        const Vec3f origin = centre + side * Vec3f(u, 0.0f, v);
        return Ray{origin, light - origin, 0.0f, 1.0f - 1e-4f};
    });
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
// and from far (tiles of them walk the top level as packets, with clipped intervals and invalid rays among
// them), shadow rays towards one light (culled from their ends), rays behind their origins, random and
// grazing ones, invalid ones among them.
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
         {far_view_rays(bounds, 48), tiled_view_rays(bounds, 48, 2.5f, 0.0f, kInfinity, 0),
          tiled_view_rays(bounds, 48, 2.5f, 0.4f, 2.5f, 0), tiled_view_rays(bounds, 48, 0.0f, -1.0f, 1.0f, 9),
          shadow_rays_to_a_light(bounds, 48, 0), shadow_rays_to_a_light(bounds, 48, 7),
          testing::random_rays(bounds, 1500, 42).rays, testing::axis_parallel_rays(bounds, 300, 43).rays,
          testing::clipped_rays(bounds, 300, 44).rays, testing::hostile_rays(bounds).rays,
          inside_and_grazing_rays(fixture, flat, 600, 45).rays, backward_rays(bounds, 300, 46)})
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
                         case_name);

// A structure that the scene can trace only through its batch calls (it has no SingleRayWalk), which
// forward to the public calls of the structure it holds. For a ray the scene hands over as it is, those
// calls find nothing to condition: the scene's answers through it are what the batch calls give.
class BatchCallsOnly final : public Accel {
  public:
    explicit BatchCallsOnly(std::shared_ptr<const Accel> held) : held_(std::move(held)) {}
    [[nodiscard]] std::string_view name() const override { return "batch_calls_only"; }
    [[nodiscard]] AccelStats stats() const override { return held_->stats(); }
    [[nodiscard]] std::size_t memory_bytes() const override { return held_->memory_bytes(); }

  protected:
    void build_structure(const Geometry& /*geometry*/, const BuildOptions& /*options*/) override {}
    UpdateReport update_structure(const Geometry& /*geometry*/) override { return {}; }
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override {
        held_->intersect(rays, hits, counters);
    }
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override {
        held_->occluded(rays, occluded, counters);
    }

  private:
    std::shared_ptr<const Accel> held_;
};

// The one-ray walks (SingleRayWalk: the objects' walk without the batch call around it, what the scene uses
// for every single-ray structure) answer as the batch calls, bit for bit: the same scene with each object
// behind BatchCallsOnly, for each single-ray structure (and bvh8_packet, traced through its bvh8) and both
// triangle tests, on the ray sets of InstancedBatches.
TEST(InstancedScene, OneRayWalksAnswerAsTheBatchCalls) {
    const Fixture fixture = random_fixture(51, 24);
    const FlatScene flat = flatten(fixture);
    for (const std::string_view name : {"brute", "grid", "kdtree", "bvh", "bvh4", "bvh8", "bvh8_packet"}) {
        for (const TriangleTest test : {TriangleTest::Watertight, TriangleTest::MollerTrumbore}) {
            InstancedScene walks, batch_calls;
            for (const std::vector<Triangle>& triangles : fixture.object_triangles) {
                const Geometry geometry{triangles, {}};
                std::shared_ptr<Accel> structure = make_accel(name);
                structure->build(geometry, build_options(test));
                auto wrapped = std::make_shared<BatchCallsOnly>(structure);
                wrapped->build(geometry, build_options(test));
                walks.add_object(structure);
                batch_calls.add_object(wrapped);
            }
            for (std::size_t i = 0; i < fixture.transforms.size(); ++i) {
                walks.add_instance(fixture.objects[i], fixture.transforms[i]);
                batch_calls.add_instance(fixture.objects[i], fixture.transforms[i]);
            }
            walks.commit();
            batch_calls.commit();
            const Box3f bounds = walks.bounds();
            std::vector<Ray> rays = testing::canonical_view_rays(bounds, 32).rays;
            for (const std::vector<Ray>& set :
                 {far_view_rays(bounds, 32), testing::random_rays(bounds, 1000, 52).rays,
                  testing::axis_parallel_rays(bounds, 200, 53).rays,
                  testing::clipped_rays(bounds, 200, 54).rays, testing::hostile_rays(bounds).rays,
                  inside_and_grazing_rays(fixture, flat, 400, 55).rays, backward_rays(bounds, 200, 56)})
                rays.insert(rays.end(), set.begin(), set.end());
            std::vector<InstanceHit> expected(rays.size()), hits(rays.size());
            std::vector<std::uint8_t> expected_occluded(rays.size()), occluded(rays.size());
            batch_calls.intersect(rays, expected);
            batch_calls.occluded(rays, expected_occluded);
            walks.intersect(rays, hits);
            walks.occluded(rays, occluded);
            std::size_t hit_count = 0;
            for (const InstanceHit& hit : expected)
                hit_count += hit.hit() ? 1 : 0;
            EXPECT_GT(hit_count, rays.size() / 5) << name;
            EXPECT_TRUE(same_hits(expected, hits))
                << name << (test == TriangleTest::Watertight ? " watertight" : " moller");
            EXPECT_EQ(occluded, expected_occluded) << name;
        }
    }
}

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
}  // namespace lancer::testing
