// What the port tests of the GPU traversals share (port_test.cpp, cwbvh_port_test.cpp): the triangle scenes,
// their ray sets, the rays conditioned as CudaTracer conditions them, and the bit-for-bit comparison.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "core/ray_conditioning.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"
#include "support/stanford_meshes.hpp"
#include "support/test_scenes.hpp"

namespace lancer::testing {

// Triangle scenes only (the GPU path traces triangles): smooth, random, flat, degenerate, and the case of a
// hit beyond the leaf's exit.
inline std::vector<TestScene> make_triangle_scenes() {
    std::vector<TestScene> scenes;
    std::mt19937 rng(77);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const auto point = [&](float scale) { return Vec3f(unit(rng), unit(rng), unit(rng)) * scale; };

    TestScene smooth{"icosphere inside a knot", {}, {}};
    make_icosphere(3, {0, 0, 0}, 0.8f).append_triangles(smooth.triangles);
    make_torus_knot(200, 8).append_triangles(smooth.triangles);
    scenes.push_back(std::move(smooth));

    TestScene soup{"triangle soup of mixed sizes", {}, {}};
    append_triangle_soup(rng, 2500, 8.0f, 7, 2.5f, 0.25f, soup.triangles);
    scenes.push_back(std::move(soup));

    TestScene grid{"a flat grid with shared edges", {}, {}};
    for (int i = 0; i < 24; ++i) {
        for (int j = 0; j < 24; ++j) {
            const float x = static_cast<float>(i), z = static_cast<float>(j);
            grid.triangles.push_back({{x, 0, z}, {x + 1, 0, z}, {x + 1, 0, z + 1}});
            grid.triangles.push_back({{x, 0, z}, {x + 1, 0, z + 1}, {x, 0, z + 1}});
        }
    }
    scenes.push_back(std::move(grid));

    TestScene degenerate{"duplicates, slivers and points", {}, {}};
    make_icosphere(2, {0, 0, 0}, 1.0f).append_triangles(degenerate.triangles);
    for (int i = 0; i < 150; ++i) {
        const Vec3f a = point(2.0f) - Vec3f(1.0f), b = point(2.0f) - Vec3f(1.0f);
        degenerate.triangles.push_back({a, b, 0.5f * (a + b)});
        degenerate.triangles.push_back({a, a, a});
        degenerate.triangles.push_back(degenerate.triangles[static_cast<std::size_t>(i)]);
    }
    scenes.push_back(std::move(degenerate));

    scenes.push_back({"one triangle", {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}}, {}});
    scenes.push_back(HitBeyondLeafExit{}.scene);
    scenes.push_back({"empty", {}, {}});
    return scenes;
}

inline std::vector<RaySet> ray_sets_for(const TestScene& scene) {
    Box3f bounds = scene.geometry().bounds();
    if (bounds.empty()) bounds = {{-1, -1, -1}, {1, 1, 1}};
    std::vector<RaySet> sets = {
        random_rays(bounds, 3000, 11), vertex_and_edge_rays(scene.triangles, 2000, 12),
        axis_parallel_rays(bounds, 2000, 13), clipped_rays(bounds, 1500, 14), hostile_rays(bounds)};
    RaySet leaf_exit{"the ray of HitBeyondLeafExit", {HitBeyondLeafExit{}.ray}};
    sets.push_back(std::move(leaf_exit));
    return sets;
}

// Bit for bit: a different float anywhere means the port does not compute what the CPU does.
inline std::size_t count_differences(std::span<const Hit> expected, std::span<const Hit> actual,
                                     std::string& first) {
    std::size_t differences = 0;
    for (std::size_t i = 0; i < expected.size(); ++i) {
        if (std::memcmp(&expected[i], &actual[i], sizeof(Hit)) == 0) continue;
        if (differences++ == 0) {
            first = "ray " + std::to_string(i) + ": expected prim " + std::to_string(expected[i].prim) +
                    " t " + std::to_string(expected[i].t) + ", got prim " + std::to_string(actual[i].prim) +
                    " t " + std::to_string(actual[i].t);
        }
    }
    return differences;
}

inline std::size_t count_hits(std::span<const Hit> hits) {
    std::size_t count = 0;
    for (const Hit& hit : hits)
        count += hit.hit() ? 1 : 0;
    return count;
}

// The rays conditioned as CudaTracer::trace conditions them on the host (src/core/ray_conditioning.hpp),
// each traced, the hits mapped back.
template <class Trace>
std::vector<Hit> trace_each(std::span<const Ray> rays, const Box3f& scene_bounds, Trace&& trace) {
    const ConditionedRays conditioned = condition_rays(rays, scene_bounds);
    const std::span<const Ray> traced =
        conditioned.rays.empty() ? rays : std::span<const Ray>(conditioned.rays);
    std::vector<Hit> hits(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i)
        hits[i] = trace(traced[i]);
    restore_hits(conditioned, rays, hits);
    return hits;
}

// Occlusion: the rays conditioned as CudaTracer conditions them, each answered by `trace` (an any-hit
// traversal: occluded when it returns a hit); nothing is mapped back.
template <class Trace>
std::vector<std::uint8_t> occlusion_each(std::span<const Ray> rays, const Box3f& scene_bounds,
                                         Trace&& trace) {
    const ConditionedRays conditioned = condition_rays(rays, scene_bounds);
    const std::span<const Ray> traced =
        conditioned.rays.empty() ? rays : std::span<const Ray>(conditioned.rays);
    std::vector<std::uint8_t> occluded(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i)
        occluded[i] = trace(traced[i]).hit() ? 1 : 0;
    return occluded;
}

inline std::size_t count_differences(std::span<const std::uint8_t> expected,
                                     std::span<const std::uint8_t> actual) {
    std::size_t differences = 0;
    for (std::size_t i = 0; i < expected.size(); ++i)
        differences += expected[i] != actual[i] ? 1 : 0;
    return differences;
}

// The bunny's canonical view at 512 x 512, loaded before the test, which is skipped when the checkout lacks
// the mesh: the ports' agreement on a real mesh.
class BunnyCanonicalView : public ::testing::Test {
  protected:
    void SetUp() override {
        const std::filesystem::path file = stanford_mesh_path("bunny.obj");
        if (!std::filesystem::exists(file))
            GTEST_SKIP() << file << " is absent (see README, 'The Stanford meshes')";
        bunny_ = std::make_unique<SceneGeometry>(load_scene(file));
        sets_ = {canonical_view_rays(bunny_->view().bounds(), kSide)};
    }
    [[nodiscard]] Geometry geometry() const { return bunny_->view(); }
    [[nodiscard]] std::span<const RaySet> sets() const { return sets_; }

    static constexpr std::size_t kSide = 512;

  private:
    std::unique_ptr<SceneGeometry> bunny_;
    std::vector<RaySet> sets_;
};

}  // namespace lancer::testing
