// The GPU kernels' two passes (src/cuda/kernels.cu, docs/cuda.md "Two passes") on the CPU: each traversal
// under FirstPass<Test>, then under Test again for the rays the first pass left kUndecided, must answer what
// the CPU structure answers, bit for bit, closest hit and occlusion alike; and the second pass must be
// reached, or the comparison would prove nothing about it.
#include <gtest/gtest.h>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/plucker/plucker.hpp"
#include "cuda/bvh_traversal.hpp"
#include "cuda/cwbvh_build.hpp"
#include "cuda/cwbvh_traversal.hpp"
#include "cuda/flatten.hpp"
#include "cuda/plucker_walk.hpp"
#include "port_scenes.hpp"

namespace lancer {
namespace {

// The rays the first pass left undecided, per traversal, summed over every scene and ray set.
struct UndecidedCounts {
    std::size_t bvh = 0, walk = 0, cwbvh = 0;
};

// `trace.template operator()<T, kAnyHit>(ray)` under FirstPass<Test>, then under Test where that answer is
// kUndecided (counted in `undecided`).
template <class Test, bool kAnyHit, class Trace>
Hit trace_two_passes(const Ray& ray, const Trace& trace, std::size_t& undecided) {
    const Hit first = trace.template operator()<gpu::FirstPass<Test>, kAnyHit>(ray);
    if (first.prim != gpu::kUndecided) return first;
    ++undecided;
    return trace.template operator()<Test, kAnyHit>(ray);
}

// One traversal's two passes against `structure` on every ray of `set`.
template <class Test, class Trace>
void expect_two_passes_agree(const Accel& structure, const testing::RaySet& set, const Trace& trace,
                             std::size_t& undecided, const std::string& where) {
    std::vector<Hit> expected(set.rays.size());
    structure.intersect(set.rays, expected);
    const auto closest = testing::trace_each(set.rays, structure.bounds(), [&](const Ray& ray) {
        return trace_two_passes<Test, false>(ray, trace, undecided);
    });
    std::string first;
    EXPECT_EQ(testing::count_differences(expected, closest, first), 0u) << where << "closest hit, " << first;

    std::vector<std::uint8_t> expected_occlusion(set.rays.size());
    structure.occluded(set.rays, expected_occlusion);
    const auto occlusion = testing::occlusion_each(set.rays, structure.bounds(), [&](const Ray& ray) {
        return trace_two_passes<Test, true>(ray, trace, undecided);
    });
    EXPECT_EQ(testing::count_differences(expected_occlusion, occlusion), 0u) << where << "occlusion";
}

template <class Test>
void expect_scene_agrees(const testing::TestScene& scene, TriangleTest test, UndecidedCounts& undecided) {
    const Geometry geometry = scene.geometry();
    const BuildOptions options = build_options(test);
    BvhAccel bvh;
    bvh.build(geometry, options);
    const gpu::FlatBvh flat = gpu::flatten_bvh(bvh, geometry);
    const gpu::BvhView bvh_view = flat.view();
    PluckerAccel plucker;
    plucker.build(geometry, options);
    const plucker::PluckerView walk_view = gpu::plucker_view(plucker.layout());
    const plucker::PluckerTables tables = plucker::kTables;
    Bvh8Accel bvh8;
    bvh8.build(geometry, options);
    const gpu::CompressedWideBvh compressed = gpu::compress_bvh8(bvh8, bvh8.built_geometry());
    const gpu::CwbvhView cwbvh_view = compressed.view();

    const auto speculative = [&]<class T, bool kAnyHit>(const Ray& ray) {
        return gpu::trace_bvh<true, T, kAnyHit>(bvh_view, ray, gpu::OtherLanesSearching{});
    };
    const auto walk = [&]<class T, bool kAnyHit>(const Ray& ray) {
        return gpu::trace_plucker<T, gpu::SeedLayout, kAnyHit>(walk_view, tables, ray);
    };
    const auto cwbvh = [&]<class T, bool kAnyHit>(const Ray& ray) {
        return gpu::trace_cwbvh<kAnyHit, T>(cwbvh_view, ray);
    };
    const std::string test_name = test == TriangleTest::Watertight ? "watertight" : "moller";
    for (const testing::RaySet& set : testing::ray_sets_for(scene)) {
        const std::string where = scene.name + ", " + set.name + ", " + test_name + ", ";
        expect_two_passes_agree<Test>(bvh, set, speculative, undecided.bvh,
                                      where + "speculative while-while: ");
        expect_two_passes_agree<Test>(plucker, set, walk, undecided.walk, where + "plucker walk: ");
        expect_two_passes_agree<Test>(bvh8, set, cwbvh, undecided.cwbvh, where + "cwbvh: ");
    }
}

TEST(CudaFirstPass, TwoPassesGiveTheWholeTestsAnswers) {
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        UndecidedCounts undecided;
        for (const testing::TestScene& scene : testing::make_triangle_scenes()) {
            if (test == TriangleTest::Watertight)
                expect_scene_agrees<Watertight>(scene, test, undecided);
            else
                expect_scene_agrees<MollerTrumbore>(scene, test, undecided);
        }
        // The rays through vertices and edges, and the degenerate scene, leave some triangles undecided.
        const char* test_name = test == TriangleTest::Watertight ? "watertight" : "moller";
        std::printf("%s: rays left undecided by the first pass: %zu (bvh), %zu (walk), %zu (cwbvh)\n",
                    test_name, undecided.bvh, undecided.walk, undecided.cwbvh);
        EXPECT_GT(undecided.bvh, 0u) << test_name;
        EXPECT_GT(undecided.walk, 0u) << test_name;
        EXPECT_GT(undecided.cwbvh, 0u) << test_name;
    }
}

}  // namespace
}  // namespace lancer
