// The helpers the fuzz regression tests share (fuzz_regression_test.cpp: the rays, the domain and the
// walks; kernel_fuzz_regression_test.cpp: the triangle and sphere tests' arithmetic).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/agreement.hpp"
#include "support/test_scenes.hpp"

namespace lancer::fuzz_regression {

using testing::TestScene;

inline std::vector<Hit> trace(const Accel& accel, std::span<const Ray> rays) {
    std::vector<Hit> hits(rays.size());
    accel.intersect(rays, hits);
    return hits;
}

inline std::vector<std::uint8_t> any_hit(const Accel& accel, std::span<const Ray> rays) {
    std::vector<std::uint8_t> occluded(rays.size());
    accel.occluded(rays, occluded);
    return occluded;
}

// Brute force's hits, then every structure but Embree (its own kernels: embree_test.cpp) against them on
// closest hit and occlusion, for each triangle test. Returns brute force's hits per test, for the caller to
// check that they are the answers it expects (a comparison of misses with misses proves nothing).
inline std::vector<std::vector<Hit>> expect_every_structure_agrees(const TestScene& scene,
                                                                   std::span<const Ray> rays) {
    std::vector<std::vector<Hit>> expected_per_test;
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const std::unique_ptr<Accel> brute = make_accel("brute");
        brute->build(scene.geometry(), build_options(test));
        const std::vector<Hit>& expected = expected_per_test.emplace_back(trace(*brute, rays));
        for (const std::string_view name : accel_names()) {
            if (name.starts_with("embree")) continue;
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(scene.geometry(), build_options(test));
            const std::string context = scene.name + ", " + std::string(name);
            EXPECT_EQ(compare_hits(rays, expected, trace(*accel, rays)).mismatches, 0u) << context;
            EXPECT_EQ(compare_occlusion(rays, expected, any_hit(*accel, rays)).mismatches, 0u) << context;
        }
    }
    return expected_per_test;
}

}  // namespace lancer::fuzz_regression
