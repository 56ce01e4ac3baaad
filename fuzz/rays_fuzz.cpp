// libFuzzer harness: `rays` queries on every registered structure (accel_names()) with both triangle
// tests. The input is a tiny scene (up to 8 triangles and 2 spheres, finite, of any magnitude) and up
// to 32 rays of arbitrary floats: NaN, infinities, zero and denormal directions, huge coordinates,
// tnear > tfar. A scene beyond the coordinate domain must be refused by every structure; otherwise every
// structure must agree with brute force (0 mismatches, include/lancer/agreement.hpp) on every ray and answer
// it cleanly (invalid rays miss); Embree, with its own kernels, must answer cleanly (accel_check.hpp).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "accel_check.hpp"
#include "fuzz_support.hpp"
#include "fuzzed_floats.hpp"

namespace lancer::fuzz {
namespace {

// A scene vertex: finite (the loaders reject the rest), of any magnitude: beyond the contract's coordinate
// domain (kCoordinateLimit) every structure must refuse the scene (findings 8 and 12, docs/robustness.md).
Vec3f next_vertex(FuzzedDataProvider& input) {
    const Vec3f v = next_vec(input);
    return is_finite(v) ? v : Vec3f(0.0f);
}

struct FuzzScene {
    std::vector<Triangle> triangles;
    std::vector<Sphere> spheres;
    std::vector<Ray> rays;

    [[nodiscard]] Geometry geometry() const { return {triangles, spheres}; }
};

FuzzScene next_scene(FuzzedDataProvider& input) {
    FuzzScene scene;
    const int triangle_count = input.ConsumeIntegralInRange(0, 8);
    for (int i = 0; i < triangle_count; ++i) {
        const Vec3f v0 = next_vertex(input), v1 = next_vertex(input);
        scene.triangles.push_back({v0, v1, next_vertex(input)});
    }
    const int sphere_count = input.ConsumeIntegralInRange(0, 2);
    for (int i = 0; i < sphere_count; ++i) {
        Sphere sphere;
        sphere.center = next_vertex(input);
        sphere.radius = std::fabs(next_float(input));
        // A positive radius and a finite box, as the loaders promise (the domain is checked by the build).
        const Box3f bounds = sphere.bounds();
        if (sphere.radius > 0.0f && is_finite(bounds.lo) && is_finite(bounds.hi))
            scene.spheres.push_back(sphere);
    }
    while (scene.rays.size() < 32 && input.remaining_bytes() > 0) {
        scene.rays.push_back(next_any_ray(input));
    }
    return scene;
}

// LANCER_FUZZ_PRINT=1 prints the decoded input (C99 hex floats), to turn a finding into a regression test.
void print(const FuzzScene& scene) {
    const auto vec = [](const Vec3f& v) { std::printf("{%a, %a, %a}", v.x, v.y, v.z); };
    for (const Triangle& triangle : scene.triangles) {
        std::printf("triangle "), vec(triangle.v0), vec(triangle.v1), vec(triangle.v2), std::printf("\n");
    }
    for (const Sphere& sphere : scene.spheres) {
        std::printf("sphere "), vec(sphere.center), std::printf(" %a\n", sphere.radius);
    }
    for (const Ray& ray : scene.rays) {
        std::printf("ray "), vec(ray.origin), vec(ray.direction),
            std::printf(" %a %a\n", ray.tnear, ray.tfar);
    }
}

bool in_coordinate_domain(const Geometry& geometry) {
    for (const Triangle& triangle : geometry.triangles) {
        if (!in_coordinate_domain(triangle.v0) || !in_coordinate_domain(triangle.v1) ||
            !in_coordinate_domain(triangle.v2))
            return false;
    }
    for (const Sphere& sphere : geometry.spheres) {
        if (!in_coordinate_domain(sphere.bounds().lo) || !in_coordinate_domain(sphere.bounds().hi))
            return false;
    }
    return true;
}

// Beyond the domain the answer is a clean refusal: std::invalid_argument from every structure's build.
void check_refused(const Geometry& geometry) {
    for (const std::string_view name : accel_names()) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        try {
            accel->build(geometry, {});
        } catch (const std::invalid_argument&) {
            continue;
        }
        finding("a structure accepted a scene outside the coordinate domain");
    }
}

}  // namespace
}  // namespace lancer::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace lancer;
    FuzzedDataProvider input(data, size);
    const fuzz::FuzzScene scene = fuzz::next_scene(input);
    if (scene.rays.empty()) return 0;
    static const bool print = std::getenv("LANCER_FUZZ_PRINT") != nullptr;
    if (print) fuzz::print(scene), std::fflush(stdout);
    const Geometry geometry = scene.geometry();
    if (!fuzz::in_coordinate_domain(geometry)) {
        fuzz::check_refused(geometry);
        return 0;
    }
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const std::vector<Hit> oracle = fuzz::oracle_hits(geometry, test, scene.rays);
        for (const std::string_view name : accel_names()) {
            if (name == "brute") continue;
            const std::unique_ptr<Accel> accel = make_accel(name);
            if (!name.starts_with("embree")) {
                accel->build(geometry, build_options(test));
                fuzz::check_clean_answers(*accel, scene.rays, geometry);
                fuzz::check_agrees_with_oracle(*accel, scene.rays, oracle, geometry);
                continue;
            }
            accel->build(geometry, build_options(test));
            fuzz::check_clean_answers(*accel, scene.rays, geometry);
        }
    }
    return 0;
}
