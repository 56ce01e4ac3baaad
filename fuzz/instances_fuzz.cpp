// libFuzzer harness: two-level scenes (lancer/instances.hpp). The input is one or two tiny objects (up to 6
// triangles each), up to 6 instances of them under transforms of any kind (rotations, scales and
// translations of any magnitude, raw 3x4 matrices: singular, NaN, ill-conditioned), and rays: up to 24 of
// arbitrary floats, a camera tile of 64 and a tile of 64 shadow rays towards one point (the two kinds of
// packet that walk the top level together, docs/accel/instances.md). The contract, for bvh8, bvh8_packet
// and brute force as the objects' structure, with both triangle tests (anything else is a finding):
// - add_instance accepts a transform or throws std::invalid_argument, the same for every structure;
// - each ray's answer in a batch is its answer alone, bit for bit (closest hit and occlusion), and clean:
//   invalid rays miss, a hit names a live instance, its object and one of its primitives, at a finite t in
//   [tnear, tfar], and a valid ray is occluded exactly when it has a closest hit;
// - bvh8's and bvh8_packet's objects answer as brute force's, bit for bit (docs/numerical-contract.md,
//   "Instances": the answer depends on the objects' answers, not on their structure or the walk's order);
// - an instance moved and committed (a refit of the top level) answers as a scene built fresh with it there.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "fuzzed_floats.hpp"
#include "lancer/instances.hpp"

namespace lancer::fuzz {
namespace {

constexpr std::size_t kTileRays = 64;

// An instance: object `mesh` placed by `object_to_world`.
using Placement = MeshInstance;

struct FuzzInstances {
    std::vector<TriangleMesh> objects;
    std::vector<Placement> placements;
    std::optional<Placement> moved;  // placements[0] moved here after the first trace
    std::vector<Ray> raw_rays;
    Vec3f eye, target;
    float tile_spread = 0.0f, tile_tnear = 0.0f, tile_tfar = kInfinity;
    Vec3f light, shadow_from, shadow_step;
};

// A finite vertex within a few units, or of any finite magnitude (the domain check is add_object's).
Vec3f next_vertex(FuzzedDataProvider& input) {
    const Vec3f v = next_vec(input);
    return is_finite(v) ? v : Vec3f(0.0f);
}

TriangleMesh next_object(FuzzedDataProvider& input) {
    TriangleMesh mesh;
    const int triangle_count = input.ConsumeIntegralInRange(1, 6);
    for (int i = 0; i < triangle_count; ++i) {
        // A vertex shared with the previous triangle now and then: edges and vertices between triangles.
        for (int corner = 0; corner < 3; ++corner) {
            if (i > 0 && corner == 0 && input.ConsumeBool()) {
                mesh.indices.push_back(mesh.indices[mesh.indices.size() - 2]);
                continue;
            }
            mesh.indices.push_back(static_cast<std::uint32_t>(mesh.positions.size()));
            mesh.positions.push_back(next_vertex(input));
        }
    }
    return mesh;
}

// A rigid or affine placement built from parts (an exact rotation about an axis, a scale, a translation),
// or a raw matrix of arbitrary floats.
Transform next_transform(FuzzedDataProvider& input) {
    if (input.ConsumeBool()) {
        Transform raw;
        for (auto& row : raw.m) {
            for (float& entry : row)
                entry = next_float(input);
        }
        return raw;
    }
    const Vec3f axis = next_vertex(input);
    const float angle = next_float(input);
    const Vec3f scale = next_vertex(input);
    const Vec3f offset = next_vertex(input);
    Transform placed = Transform::translation(offset);
    if (axis != Vec3f(0.0f) && std::isfinite(angle)) placed = placed * Transform::rotation(axis, angle);
    if (scale.x != 0.0f && scale.y != 0.0f && scale.z != 0.0f) placed = placed * Transform::scaling(scale);
    return placed;
}

FuzzInstances next_input(FuzzedDataProvider& input) {
    FuzzInstances scene;
    const int object_count = input.ConsumeIntegralInRange(1, 2);
    for (int i = 0; i < object_count; ++i)
        scene.objects.push_back(next_object(input));
    const int instance_count = input.ConsumeIntegralInRange(1, 6);
    for (int i = 0; i < instance_count; ++i) {
        Placement placement;
        placement.mesh = input.ConsumeIntegralInRange<std::uint32_t>(0, object_count - 1);
        // A copy of an earlier placement now and then: identical instances, whose hits tie.
        placement.object_to_world = i > 0 && input.ConsumeIntegralInRange(0, 7) == 0
                                        ? scene.placements.back().object_to_world
                                        : next_transform(input);
        scene.placements.push_back(placement);
    }
    if (input.ConsumeBool()) scene.moved = Placement{scene.placements[0].mesh, next_transform(input)};
    scene.eye = next_vec(input);
    scene.target = next_vec(input);
    scene.tile_spread = next_float(input);
    scene.tile_tnear = input.ConsumeBool() ? 0.0f : next_float(input);
    scene.tile_tfar = input.ConsumeBool() ? kInfinity : next_float(input);
    scene.light = next_vec(input);
    scene.shadow_from = next_vec(input);
    scene.shadow_step = next_vec(input);
    while (scene.raw_rays.size() < 24 && input.remaining_bytes() > 0) {
        scene.raw_rays.push_back(next_any_ray(input));
    }
    return scene;
}

// The rays traced: the raw ones, then an 8x8 camera tile from `eye` towards a patch around `target`, then
// an 8x8 tile of shadow rays from a grid of points towards `light` (direction light - origin, [0, 1 - 1e-4]
// as the shadow view's), each tile starting at a multiple of 64 so that a batch walks it as one packet.
std::vector<Ray> rays_of(const FuzzInstances& scene) {
    std::vector<Ray> rays = scene.raw_rays;
    rays.resize(kTileRays, Ray{{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 0.0f, 0.0f});  // invalid padding
    for (std::size_t k = 0; k < kTileRays; ++k) {
        const float u = static_cast<float>(k % 8) - 3.5f, v = static_cast<float>(k / 8) - 3.5f;
        const Vec3f aim = scene.target + scene.tile_spread * Vec3f(u, v, 0.25f * u * v);
        rays.push_back({scene.eye, aim - scene.eye, scene.tile_tnear, scene.tile_tfar});
    }
    for (std::size_t k = 0; k < kTileRays; ++k) {
        const float u = static_cast<float>(k % 8), v = static_cast<float>(k / 8);
        const Vec3f origin = scene.shadow_from + u * scene.shadow_step +
                             v * Vec3f(scene.shadow_step.z, scene.shadow_step.x, 0.0f);
        rays.push_back({origin, scene.light - origin, 0.0f, 1.0f - 1e-4f});
    }
    return rays;
}

// LANCER_FUZZ_PRINT=1 prints the decoded input (C99 hex floats), to turn a finding into a regression test.
void print(const FuzzInstances& scene, std::span<const Ray> rays) {
    const auto vec = [](const Vec3f& v) { std::printf("{%a, %a, %a}", v.x, v.y, v.z); };
    for (std::size_t o = 0; o < scene.objects.size(); ++o) {
        const TriangleMesh& mesh = scene.objects[o];
        for (std::size_t i = 0; i < mesh.triangle_count(); ++i) {
            const Triangle t = mesh.triangle(i);
            std::printf("object %zu triangle ", o), vec(t.v0), vec(t.v1), vec(t.v2), std::printf("\n");
        }
    }
    const auto transform = [](const Placement& p) {
        std::printf("object %u transform", p.mesh);
        for (const auto& row : p.object_to_world.m)
            std::printf(" {%a, %a, %a, %a}", row[0], row[1], row[2], row[3]);
        std::printf("\n");
    };
    for (const Placement& placement : scene.placements)
        std::printf("instance: "), transform(placement);
    if (scene.moved) std::printf("instance 0 moved to: "), transform(*scene.moved);
    for (const Ray& ray : rays) {
        std::printf("ray "), vec(ray.origin), vec(ray.direction),
            std::printf(" %a %a\n", ray.tnear, ray.tfar);
    }
}

struct Built {
    InstancedScene scene;
    std::vector<bool> accepted;                // per placement: add_instance took it
    std::vector<std::size_t> triangle_counts;  // per object
};

// The scene over `placements` with `accel` as the objects' structure; nullopt when an object is refused
// (outside the coordinate domain: rays_fuzz checks the structures' refusal).
std::optional<Built> build(const FuzzInstances& input, const std::vector<Placement>& placements,
                           std::string_view accel, TriangleTest test) {
    Built built;
    try {
        for (const TriangleMesh& mesh : input.objects) {
            built.scene.add_object(mesh, accel, build_options(test));
            built.triangle_counts.push_back(mesh.triangle_count());
        }
    } catch (const std::invalid_argument&) {
        return std::nullopt;
    }
    for (const Placement& placement : placements) {
        try {
            built.scene.add_instance(placement.mesh, placement.object_to_world);
            built.accepted.push_back(true);
        } catch (const std::invalid_argument&) {
            built.scene.skip_instance_id();
            built.accepted.push_back(false);
        }
    }
    built.scene.commit();
    return built;
}

bool same_hit(const InstanceHit& a, const InstanceHit& b) {
    return std::memcmp(&a, &b, sizeof(InstanceHit)) == 0;
}

struct Answers {
    std::vector<InstanceHit> hits;
    std::vector<std::uint8_t> occluded;
};

// The batch's answers, checked against each ray's answer alone and for cleanliness.
Answers trace_and_check(const Built& built, std::span<const Ray> rays, const std::string& who) {
    const InstancedScene& scene = built.scene;
    const std::vector<bool>& accepted = built.accepted;
    Answers batch{std::vector<InstanceHit>(rays.size()), std::vector<std::uint8_t>(rays.size(), 2)};
    scene.intersect(rays, batch.hits);
    scene.occluded(rays, batch.occluded);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        // The message is made only for a finding: an input checks over a thousand answers.
        const auto fail = [&](std::string_view what) {
            finding(who + ", ray " + std::to_string(i) + ": " + std::string(what));
        };
        InstanceHit alone;
        std::uint8_t occluded_alone = 2;
        scene.intersect(rays.subspan(i, 1), {&alone, 1});
        scene.occluded(rays.subspan(i, 1), {&occluded_alone, 1});
        if (!same_hit(alone, batch.hits[i])) fail("its closest hit in a batch is not its hit alone");
        if (occluded_alone != batch.occluded[i]) fail("its occlusion in a batch is not its own alone");
        const InstanceHit& hit = batch.hits[i];
        if (batch.occluded[i] > 1) fail("occlusion is neither 0 nor 1");
        if (!is_valid(rays[i])) {
            if (hit.hit() || batch.occluded[i] != 0) fail("an invalid ray found something");
            continue;
        }
        if ((batch.occluded[i] != 0) != hit.hit()) fail("occluded is not 'has a closest hit'");
        if (!hit.hit()) {
            if (hit.t != kInfinity || hit.prim != -1 || hit.instance != -1 || hit.object != -1)
                fail("a miss is not (t = +inf, prim = instance = object = -1)");
            continue;
        }
        if (hit.instance < 0 || static_cast<std::size_t>(hit.instance) >= accepted.size() ||
            !accepted[static_cast<std::size_t>(hit.instance)])
            fail("a hit names instance " + std::to_string(hit.instance) + ", not a live one");
        if (static_cast<std::uint32_t>(hit.object) !=
            scene.object_of(static_cast<std::uint32_t>(hit.instance)))
            fail("a hit names another object than its instance's");
        if (static_cast<std::size_t>(hit.prim) >= built.triangle_counts[static_cast<std::size_t>(hit.object)])
            fail("a hit names a primitive its object does not hold");
        if (!std::isfinite(hit.t) || hit.t < rays[i].tnear || hit.t > rays[i].tfar)
            fail("a hit's t lies outside [tnear, tfar]");
    }
    return batch;
}

std::string describe(const InstanceHit& hit) {
    char text[160];
    std::snprintf(text, sizeof text, "(t %a, prim %d, u %a, v %a, instance %d, object %d)", hit.t, hit.prim,
                  hit.u, hit.v, hit.instance, hit.object);
    return text;
}

void check_same(const Answers& expected, const Answers& actual, const std::string& who) {
    for (std::size_t i = 0; i < expected.hits.size(); ++i) {
        if (!same_hit(expected.hits[i], actual.hits[i]))
            finding(who + ", ray " + std::to_string(i) + ": closest hits differ: " +
                    describe(expected.hits[i]) + " against " + describe(actual.hits[i]));
        if (expected.occluded[i] != actual.occluded[i])
            finding(who + ", ray " + std::to_string(i) + ": occlusion differs");
    }
}

}  // namespace
}  // namespace lancer::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace lancer;
    using namespace lancer::fuzz;
    FuzzedDataProvider provider(data, size);
    const FuzzInstances input = next_input(provider);
    const std::vector<Ray> rays = rays_of(input);
    static const bool print_input = std::getenv("LANCER_FUZZ_PRINT") != nullptr;
    if (print_input) print(input, rays), std::fflush(stdout);
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const std::string test_name = test == TriangleTest::Watertight ? "watertight" : "moller";
        std::optional<Built> reference = build(input, input.placements, "brute", test);
        if (!reference) return 0;
        const Answers expected = trace_and_check(*reference, rays, "brute " + test_name);
        for (const std::string_view accel : {"bvh8", "bvh8_packet"}) {
            const std::string who = std::string(accel) + " " + test_name;
            std::optional<Built> built = build(input, input.placements, accel, test);
            if (!built) finding(who + ": an object brute force took was refused");
            if (built->accepted != reference->accepted)
                finding(who + ": add_instance accepted other transforms than with brute force's objects");
            check_same(expected, trace_and_check(*built, rays, who), who + " vs brute");
            if (!input.moved || !built->accepted[0]) continue;
            // Instance 0 moved: a refit of the top level answers as a scene built with it there.
            std::vector<Placement> moved_placements = input.placements;
            moved_placements[0] = *input.moved;
            std::optional<Built> fresh = build(input, moved_placements, accel, test);
            if (!fresh) finding(who + ": an object was refused the second time");
            bool moved = true;
            try {
                built->scene.set_transform(0, input.moved->object_to_world);
            } catch (const std::invalid_argument&) {
                moved = false;
            }
            if (moved != fresh->accepted[0])
                finding(who + ": set_transform and add_instance disagree on a transform");
            if (!moved) continue;
            built->scene.commit();
            check_same(trace_and_check(*fresh, rays, who + " fresh"),
                       trace_and_check(*built, rays, who + " moved"), who + " moved vs fresh");
        }
    }
    return 0;
}
