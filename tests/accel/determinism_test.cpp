// Deterministic answers (STYLE.md, habit 7): the same scene and rays give bit-identical answers whatever the
// thread count of the build, the thread count of the trace and the run. Each registered structure is built in
// a one-thread arena and twice in a four-thread arena (once under the sanitizers), and each build traces the
// same rays in batches (as `lancer rays` and the renderer split them) over 1, 2 and 4 threads: every Hit
// array must equal the first byte for byte, every occlusion array likewise. The structures built on the
// binary BVH run again with spatial splits. The structural equality of parallel builds is tested beside each
// structure.
#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <array>
#include <cmath>
#include <cstring>
#include <optional>
#include <random>
#include <string_view>
#include <utility>

#include "lancer/accel.hpp"
#include "lancer/generate.hpp"
#include "support/configurations.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::TestScene;

// Small batches, so that 4 threads really interleave them.
constexpr std::size_t kBatch = 512;

// Knot segments: 2800 x 12 sides x 2 = 67200 triangles puts the BVH past its parallel binning threshold
// (65536) as well as its parallel subtrees (4096). Brute force has no build to parallelise and tests every
// primitive per ray: it gets an icosphere of 320 and a knot of 2 x 30 x 12 = 720 triangles. The kd-tree and
// the octree parallelise subtrees alone (from 4096 references); under the sanitizers their builds take seven
// to ten times their release time, and there a quarter of the knot (16,800 triangles) still passes that
// threshold.
int knot_segments_for(std::string_view structure) {
    if (structure == "brute") return 30;
    if (structure == "kdtree" || structure == "octree")
        return 2800 / static_cast<int>(testing::kSanitizedShare);
    return 2800;
}

TestScene mixed_scene(int icosphere_subdivisions, int knot_segments) {
    TestScene scene{"icosphere, knot, spheres and coincident triangles", {}, {}};
    make_icosphere(icosphere_subdivisions, {0, 0, 0}, 1.0f).append_triangles(scene.triangles);
    make_torus_knot(knot_segments, 12).append_triangles(scene.triangles);
    // Exact ties: the same triangle twice, so that the closest hit must be broken by index every time.
    scene.triangles.push_back({{-2, -2, 1.5f}, {2, -2, 1.5f}, {0, 2, 1.5f}});
    scene.triangles.push_back({{-2, -2, 1.5f}, {2, -2, 1.5f}, {0, 2, 1.5f}});
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(-2.0f, 2.0f);
    for (int i = 0; i < 30; ++i)
        scene.spheres.push_back({{unit(rng), unit(rng), unit(rng)}, 0.1f + 0.05f * std::abs(unit(rng)), 0});
    return scene;
}

std::unique_ptr<Accel> build_in_arena(const testing::Configuration& configuration, const Geometry& geometry,
                                      TriangleTest test, int threads) {
    std::unique_ptr<Accel> accel = make_accel(configuration.name);
    tbb::task_arena(threads).execute([&] { accel->build(geometry, configuration.options(test)); });
    return accel;
}

struct Answers {
    std::vector<Hit> hits;
    std::vector<std::uint8_t> occluded;
};

Answers trace_in_batches(const Accel& accel, std::span<const Ray> rays, int threads) {
    Answers answers{std::vector<Hit>(rays.size()), std::vector<std::uint8_t>(rays.size())};
    tbb::task_arena(threads).execute([&] {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), kBatch), [&](const auto& range) {
            accel.intersect(rays.subspan(range.begin(), range.size()),
                            std::span(answers.hits).subspan(range.begin(), range.size()));
            accel.occluded(rays.subspan(range.begin(), range.size()),
                           std::span(answers.occluded).subspan(range.begin(), range.size()));
        });
    });
    return answers;
}

// The builds compared: on one thread, then twice on four (the same thread count, run again). A sanitized
// build, which checks memory rather than answers, leaves out the run again: the four-thread build's code is
// the same both times.
#ifdef LANCER_SANITIZED
constexpr std::array<std::pair<int, int>, 2> kBuilds = {{{1, 0}, {4, 0}}};
#else
constexpr std::array<std::pair<int, int>, 3> kBuilds = {{{1, 0}, {4, 0}, {4, 1}}};
#endif

class Determinism : public ::testing::TestWithParam<testing::Configuration> {};

TEST_P(Determinism, HitsAreBitIdenticalWhateverTheThreadsAndTheRun) {
    const TestScene scene =
        mixed_scene(GetParam().name == "brute" ? 2 : 3, knot_segments_for(GetParam().name));
    const Box3f bounds = scene.geometry().bounds();
    constexpr std::size_t share = testing::kSanitizedShare;
    std::vector<Ray> rays = testing::random_rays(bounds, 12'000 / share, 31).rays;
    for (const Ray& ray : testing::vertex_and_edge_rays(scene.triangles, 6'000 / share, 32).rays)
        rays.push_back(ray);
    for (const Ray& ray : testing::axis_parallel_rays(bounds, 4'000 / share, 33).rays)
        rays.push_back(ray);

    for (TriangleTest test : {TriangleTest::Watertight, TriangleTest::MollerTrumbore}) {
        const char* test_name = test == TriangleTest::Watertight ? "watertight" : "moller";
        std::optional<Answers> first;
        std::size_t hit_count = 0;
        for (const auto& [build_threads, run] : kBuilds) {
            const std::unique_ptr<Accel> accel =
                build_in_arena(GetParam(), scene.geometry(), test, build_threads);
            for (int trace_threads : {1, 2, 4}) {
                const Answers answers = trace_in_batches(*accel, rays, trace_threads);
                if (!first) {
                    first = answers;
                    for (const Hit& hit : answers.hits)
                        hit_count += hit.hit();
                    continue;
                }
                const std::string where =
                    std::string(test_name) + ", built on " + std::to_string(build_threads) +
                    " threads (run " + std::to_string(run) + "), traced on " + std::to_string(trace_threads);
                EXPECT_EQ(std::memcmp(answers.hits.data(), first->hits.data(), rays.size() * sizeof(Hit)), 0)
                    << where;
                EXPECT_EQ(answers.occluded, first->occluded) << where;
            }
        }
        // The comparison means something only if the rays find the scene.
        EXPECT_GT(hit_count, rays.size() / 4) << test_name;
    }
}

INSTANTIATE_TEST_SUITE_P(Structures, Determinism,
                         ::testing::ValuesIn(testing::agreement_configurations(accel_names())),
                         [](const auto& param_info) { return param_info.param.label(); });

}  // namespace
}  // namespace lancer
