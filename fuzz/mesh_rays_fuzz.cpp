// libFuzzer harness: `rays` queries on deep structures. rays_fuzz builds every structure on a tiny fuzzed
// scene, so its trees are a leaf or two deep. Here every structure is built once, at start, in both triangle
// tests, on five fixed scenes of 578 to 1,280 primitives with small leaves and raised depth limits, and only
// the rays are fuzzed. That reaches what a tiny scene cannot: deep trees, the Plücker octree's deeper levels
// and its links between leaves of different sizes, long leaf-to-leaf walks, full traversal stacks, leaves of
// coincident triangles at the depth limit.
//
// Rays start at, and aim at, the scenes' shared vertices, points on their shared edges (on the 1/16 lattice
// of the edge parameter, and one float either side of it), points inside their triangles, the exact centre
// of a closed mesh, or anywhere (the floats of rays_fuzz: NaN, infinities, zero and denormal components,
// huge values); an aimed direction may be scaled by any power of two or nudged by a few floats off the
// aimed-at line.
//
// The contract (docs/robustness.md, "Harnesses and their contracts"): every structure but Embree agrees
// with brute force on closest hit and occlusion (0 mismatches) and answers cleanly; Embree answers cleanly
// in its three packet modes; and, the leak test's property on any direction, a valid ray from the exact
// centre of a closed mesh over [tnear <= 0, +inf] hits in watertight mode (docs/numerical-contract.md).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/octree_build.hpp"
#include "accel/plucker/plucker.hpp"
#include "accel_check.hpp"
#include "fuzz_support.hpp"
#include "fuzzed_floats.hpp"
#include "lancer/generate.hpp"

namespace lancer::fuzz {
namespace {

constexpr std::size_t kMaxRays = 16;
constexpr std::array kTriangleTests = {TriangleTest::MollerTrumbore, TriangleTest::Watertight};

// A fixed scene with every structure built on it, in both triangle tests.
struct DeepScene {
    std::string name;
    std::vector<Triangle> triangles;
    std::vector<Sphere> spheres;
    // A point strictly inside a closed mesh of the scene, with exact coordinates: a ray from it must hit.
    std::optional<Vec3f> enclosed_point;
    // The octrees' depth limit: 9, or 6 at 1e6, where the geometric tolerance (about a unit there) grows
    // every triangle into its neighbours' cells and leaves of 2 would split the whole surface to the limit
    // (851 MB for the Plücker octree at depth 9).
    int octree_depth = 9;
    Box3f bounds;
    struct Built {
        std::unique_ptr<Accel> brute;
        std::vector<std::unique_ptr<Accel>> held_to_oracle;  // every structure but brute and Embree
        std::vector<std::unique_ptr<Accel>> embree;          // one per Embree call, held to clean answers
    };
    std::array<Built, kTriangleTests.size()> built;

    [[nodiscard]] Geometry geometry() const { return {triangles, spheres}; }
};

DeepScene mesh_scene(std::string name, const TriangleMesh& mesh, std::optional<Vec3f> inside) {
    DeepScene scene;
    scene.name = std::move(name);
    mesh.append_triangles(scene.triangles);
    scene.enclosed_point = inside;
    return scene;
}

// An icosphere whose x is stretched by 2^12 (exactly): long thin boxes and cells, a needle's far rays.
TriangleMesh stretched_icosphere() {
    TriangleMesh mesh = make_icosphere(3);
    for (Vec3f& position : mesh.positions)
        position.x *= 0x1p12f;
    return mesh;
}

// What the oracle test calls hostile, at the depth limit: duplicates, 150 coincident copies of one
// triangle (a leaf no split can empty), zero-area triangles (collinear and points) on the mesh's own
// edges and vertices, a large triangle through the middle, a zero-radius sphere on a vertex. The closed
// icosphere is still there around its centre.
DeepScene clutter() {
    DeepScene scene = mesh_scene("clutter", make_icosphere(2), Vec3f(0.0f));
    const std::size_t mesh_size = scene.triangles.size();
    for (std::size_t i = 0; i < 40; ++i)
        scene.triangles.push_back(scene.triangles[i]);
    for (int i = 0; i < 150; ++i)
        scene.triangles.push_back(scene.triangles[0]);
    for (std::size_t i = 0; i < mesh_size; i += 10) {
        const Triangle triangle = scene.triangles[i];
        scene.triangles.push_back({triangle.v0, triangle.v1, (triangle.v0 + triangle.v1) * 0.5f});
        scene.triangles.push_back({triangle.v2, triangle.v2, triangle.v2});
    }
    scene.triangles.push_back({{-8.0f, -8.0f, 0.0625f}, {8.0f, -8.0f, 0.0625f}, {0.0f, 8.0f, 0.0625f}});
    scene.spheres.push_back({scene.triangles[5].v1, 0.0f});
    scene.spheres.push_back({{0.5f, 0.0f, 0.0f}, 1e-3f});
    scene.spheres.push_back({scene.triangles[9].v2, 0.25f});
    return scene;
}

// Options that make every tree deep on a scene of a thousand primitives: small leaves and raised depth
// limits (the automatic Plücker depth for 1,280 triangles is 3). `variants` selects the Plücker octree's
// section 6 variants (no 2:1 rule, planes recomputed, Morton order) instead of the defaults.
BuildOptions deep_options(TriangleTest test, int octree_depth, bool variants) {
    BuildOptions options = build_options(test);
    options.group<OctreeOptions>().max_depth = octree_depth;
    options.group<OctreeOptions>().leaf_size = 2;
    options.group<PluckerOptions>().max_depth = octree_depth;
    options.group<PluckerOptions>().leaf_size = 2;
    options.group<PluckerOptions>().balanced = !variants;
    options.group<PluckerOptions>().stored_boxes = !variants;
    options.group<PluckerOptions>().morton = variants;
    options.group<BvhOptions>().max_leaf_size = 1;
    return options;
}

void build_every_structure(DeepScene& scene, bool variants) {
    const Geometry geometry = scene.geometry();
    scene.bounds = geometry.bounds();
    for (std::size_t t = 0; t < kTriangleTests.size(); ++t) {
        DeepScene::Built& built = scene.built[t];
        for (const std::string_view name : accel_names()) {
            std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(geometry, deep_options(kTriangleTests[t], scene.octree_depth, variants));
            if (name == "brute")
                built.brute = std::move(accel);
            else if (name.starts_with("embree"))
                built.embree.push_back(std::move(accel));
            else
                built.held_to_oracle.push_back(std::move(accel));
        }
    }
}

std::vector<DeepScene>& deep_scenes() {
    static std::vector<DeepScene> scenes;
    return scenes;
}

// A parameter along an edge or across a triangle: a multiple of 1/16 in [0, 1], or the float beside it.
float next_parameter(FuzzedDataProvider& input) {
    const int tag = input.ConsumeIntegral<std::uint8_t>();
    const float lattice = static_cast<float>(tag % 17) / 16.0f;
    switch ((tag / 17) % 3) {
        case 0:
            return lattice;
        case 1:
            return std::nextafter(lattice, -1.0f);
        default:
            return std::nextafter(lattice, 2.0f);
    }
}

// A point on a triangle of the scene: a vertex (kind 0), on an edge or a float off it (1), or in the plane
// of the triangle at lattice barycentrics, inside or out (2).
Vec3f next_point_on_triangle(FuzzedDataProvider& input, const DeepScene& scene, int kind) {
    const Triangle& triangle =
        scene.triangles[input.ConsumeIntegral<std::uint16_t>() % scene.triangles.size()];
    const std::array corners = {triangle.v0, triangle.v1, triangle.v2};
    const int corner = input.ConsumeIntegral<std::uint8_t>() % 3;
    const Vec3f from = corners[corner], to = corners[(corner + 1) % 3];
    if (kind == 0) return from;
    if (kind == 1) return from + next_parameter(input) * (to - from);
    const float u = next_parameter(input), v = next_parameter(input);
    return triangle.v0 + u * (triangle.v1 - triangle.v0) + v * (triangle.v2 - triangle.v0);
}

// A point to start from or aim at.
Vec3f next_point(FuzzedDataProvider& input, const DeepScene& scene) {
    const int kind = input.ConsumeIntegral<std::uint8_t>() % 6;
    switch (kind) {
        case 0:
        case 1:
        case 2:
            return next_point_on_triangle(input, scene, kind);
        case 3:
            return scene.enclosed_point.value_or(scene.bounds.center());
        case 4:
            return scene.bounds.center() + next_vec(input) * max_component(scene.bounds.extent());
        default:
            return next_vec(input);  // anywhere, any float
    }
}

// Off an aimed direction: a power of two (the line kept exactly; extreme scales for ray conditioning), or
// a few floats of one component (a line beside the aimed-at vertex or edge).
Vec3f next_direction(FuzzedDataProvider& input, const DeepScene& scene, Vec3f origin) {
    const int kind = input.ConsumeIntegral<std::uint8_t>() % 4;
    if (kind == 0) return next_vec(input);
    const Vec3f aimed = next_point(input, scene) - origin;
    if (kind == 1) return aimed;
    if (kind == 2) {
        const int exponent = input.ConsumeIntegralInRange(-160, 160);
        return {std::ldexp(aimed.x, exponent), std::ldexp(aimed.y, exponent), std::ldexp(aimed.z, exponent)};
    }
    Vec3f nudged = aimed;
    float* const component =
        std::array{&nudged.x, &nudged.y, &nudged.z}[input.ConsumeIntegral<std::uint8_t>() % 3];
    const int steps = input.ConsumeIntegralInRange(-4, 4);
    for (int i = 0; i < std::abs(steps); ++i)
        *component = std::nextafter(*component, steps < 0 ? -kInfinity : kInfinity);
    return nudged;
}

Ray next_ray(FuzzedDataProvider& input, const DeepScene& scene) {
    Ray ray;
    ray.origin = next_point(input, scene);
    ray.direction = next_direction(input, scene, ray.origin);
    // An aimed ray reaches its target at t = 1: tfar there, or a float short of it.
    ray.tnear = input.ConsumeBool() ? 0.0f : next_float(input);
    switch (input.ConsumeIntegral<std::uint8_t>() % 4) {
        case 0:
            ray.tfar = kInfinity;
            break;
        case 1:
            ray.tfar = 1.0f;
            break;
        case 2:
            ray.tfar = std::nextafter(1.0f, 0.0f);
            break;
        default:
            ray.tfar = next_float(input);
            break;
    }
    return ray;
}

// LANCER_FUZZ_PRINT=1 prints the decoded rays (C99 hex floats), to turn a finding into a regression test.
void print(const DeepScene& scene, const std::vector<Ray>& rays) {
    std::printf("scene %s\n", scene.name.c_str());
    for (const Ray& ray : rays) {
        std::printf("ray {%a, %a, %a} {%a, %a, %a} %a %a\n", ray.origin.x, ray.origin.y, ray.origin.z,
                    ray.direction.x, ray.direction.y, ray.direction.z, ray.tnear, ray.tfar);
    }
}

// From strictly inside a closed mesh every valid ray that looks forward without end hits it: the leak
// test's property (tests/accel/leak_test.cpp), here on fuzzed directions, and with every structure through
// the oracle agreement. Unless the hit lies beyond t = FLT_MAX, where the contract answers a miss (a
// direction scaled down to a denormal): the hit point lies within the box, so t <= reach / max|d|.
void check_enclosed_rays_hit(const DeepScene& scene, const std::vector<Ray>& rays,
                             const std::vector<Hit>& watertight_hits) {
    if (!scene.enclosed_point) return;
    const Vec3f inside = *scene.enclosed_point;
    const double reach =
        std::max(max_component(scene.bounds.hi - inside), max_component(inside - scene.bounds.lo));
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Ray& ray = rays[i];
        const bool from_inside =
            ray.origin.x == inside.x && ray.origin.y == inside.y && ray.origin.z == inside.z;
        const bool finite_t = reach / max_component(abs(ray.direction)) < 0x1p127;
        if (from_inside && is_valid(ray) && finite_t && ray.tnear <= 0.0f && ray.tfar == kInfinity &&
            !watertight_hits[i].hit())
            finding(scene.name + ": a ray from inside the closed mesh leaked in watertight mode (ray " +
                    std::to_string(i) + ")");
    }
}

}  // namespace
}  // namespace lancer::fuzz

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    using namespace lancer;
    std::vector<fuzz::DeepScene>& scenes = fuzz::deep_scenes();
    const Vec3f far_center(1e6f, -1e6f, 1e6f);
    scenes.push_back(fuzz::mesh_scene("icosphere", make_icosphere(3), Vec3f(0.0f)));
    scenes.push_back(fuzz::mesh_scene("icosphere at 1e6", make_icosphere(3, far_center, 50.0f), far_center));
    scenes.back().octree_depth = 6;
    scenes.push_back(fuzz::mesh_scene("stretched icosphere", fuzz::stretched_icosphere(), Vec3f(0.0f)));
    scenes.push_back(fuzz::mesh_scene("torus knot", make_torus_knot(50, 12), std::nullopt));
    scenes.push_back(fuzz::clutter());
    for (std::size_t i = 0; i < scenes.size(); ++i)
        fuzz::build_every_structure(scenes[i], i % 2 == 1);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace lancer;
    FuzzedDataProvider input(data, size);
    const std::vector<fuzz::DeepScene>& scenes = fuzz::deep_scenes();
    const fuzz::DeepScene& scene = scenes[input.ConsumeIntegral<std::uint8_t>() % scenes.size()];
    std::vector<Ray> rays;
    while (rays.size() < fuzz::kMaxRays && input.remaining_bytes() > 0)
        rays.push_back(fuzz::next_ray(input, scene));
    if (rays.empty()) return 0;
    static const bool print = std::getenv("LANCER_FUZZ_PRINT") != nullptr;
    if (print) fuzz::print(scene, rays), std::fflush(stdout);
    const Geometry geometry = scene.geometry();
    for (std::size_t t = 0; t < fuzz::kTriangleTests.size(); ++t) {
        const fuzz::DeepScene::Built& built = scene.built[t];
        const std::vector<Hit> oracle = fuzz::oracle_hits(*built.brute, rays, geometry);
        if (fuzz::kTriangleTests[t] == TriangleTest::Watertight)
            fuzz::check_enclosed_rays_hit(scene, rays, oracle);
        for (const std::unique_ptr<Accel>& accel : built.held_to_oracle)
            fuzz::check_agrees_with_oracle(*accel, rays, oracle, geometry);
        for (const std::unique_ptr<Accel>& accel : built.embree)
            fuzz::check_clean_answers(*accel, rays, geometry);
    }
    return 0;
}
