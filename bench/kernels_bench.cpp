// Kernel throughput: one triangle test (both variants), one slab test, one sphere test, per call.
// Inputs are random but fixed (seeded), and half of the rays hit, so branch prediction is not flattered.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "core/intersect.hpp"

namespace lancer {
namespace {

constexpr std::size_t kCount = 4096;

struct Inputs {
    std::vector<Ray> rays;
    std::vector<Triangle> triangles;
    std::vector<Box3f> boxes;
};

const Inputs& inputs() {
    static const Inputs data = [] {
        std::mt19937 rng(42);
        std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
        auto point = [&] { return Vec3f(coordinate(rng), coordinate(rng), coordinate(rng)); };
        Inputs made;
        for (std::size_t i = 0; i < kCount; ++i) {
            const Triangle tri{point(), point(), point()};
            const Vec3f origin = point() * 4.0f;
            const Vec3f target = i % 2 ? tri.bounds().center() : point() * 2.0f;
            made.triangles.push_back(tri);
            made.boxes.push_back(tri.bounds());
            made.rays.push_back({origin, target - origin, 0.0f, kInfinity});
        }
        return made;
    }();
    return data;
}

template <class TriangleTestT>
void BM_Triangle(benchmark::State& state) {
    const Inputs& in = inputs();
    std::vector<typename TriangleTestT::RayData> prepared;
    for (const Ray& ray : in.rays)
        prepared.emplace_back(ray);
    std::size_t i = 0;
    for (auto _ : state) {
        TriangleHit hit;
        benchmark::DoNotOptimize(
            TriangleTestT::intersect(prepared[i], in.triangles[i], 0.0f, kInfinity, hit));
        benchmark::DoNotOptimize(hit);
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Triangle<MollerTrumbore>)->Name("triangle/moller_trumbore");
BENCHMARK(BM_Triangle<Watertight>)->Name("triangle/watertight");

void BM_Box(benchmark::State& state) {
    const Inputs& in = inputs();
    std::vector<SlabRay> prepared;
    for (const Ray& ray : in.rays)
        prepared.emplace_back(ray);
    std::size_t i = 0;
    for (auto _ : state) {
        float entry, exit;
        benchmark::DoNotOptimize(intersect_box(prepared[i], in.boxes[i], 0.0f, kInfinity, entry, exit));
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Box)->Name("box/slab");

void BM_Sphere(benchmark::State& state) {
    const Inputs& in = inputs();
    std::size_t i = 0;
    for (auto _ : state) {
        TriangleHit hit;
        const Sphere sphere{in.boxes[i].center(), 0.5f, 0};
        benchmark::DoNotOptimize(intersect_sphere(in.rays[i], sphere, 0.0f, kInfinity, hit));
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Sphere)->Name("sphere/haines");

}  // namespace
}  // namespace lancer
