// The Plücker octree's layout variants (section 6 of Portalez & Duguet 2016: no 2:1 rule, no stored boxes,
// Morton order, and their combinations) on the Stanford meshes: every ray of the canonical view and 10^6
// random rays, against the BVH (which stanford_test.cpp checks against brute force on a sample). The
// registry's default layout is covered by stanford_test.cpp itself. A sanitized build traces
// 1/testing::kSanitizedStride of each.
#include <gtest/gtest.h>

#include "accel/plucker/plucker.hpp"
#include "lancer/agreement.hpp"
#include "support/ray_sets.hpp"
#include "support/stanford_meshes.hpp"

namespace lancer {
namespace {

class PluckerStanford : public testing::StanfordMeshTest {};

TEST_P(PluckerStanford, EveryLayoutAgreesWithTheBvh) {
    const SceneGeometry& geometry = mesh();
    const Box3f bounds = geometry.view().bounds();
    std::vector<testing::RaySet> sets = {testing::canonical_view_rays(bounds),
                                         testing::random_rays(bounds, 1'000'000, 19)};
    for (testing::RaySet& set : sets)
        testing::keep_every(set, testing::kSanitizedStride);
    const std::unique_ptr<Accel> reference = make_accel("bvh");
    reference->build(geometry.view(), {});
    std::vector<std::vector<Hit>> expected;
    for (const testing::RaySet& set : sets)
        expected.push_back(testing::trace_in_parallel(*reference, set.rays));

    for (int variant = 1; variant < 8; ++variant) {  // variant 0 is the default, in stanford_test.cpp
        BuildOptions options;
        options.group<PluckerOptions>().balanced = (variant & 1) == 0;
        options.group<PluckerOptions>().stored_boxes = (variant & 2) == 0;
        options.group<PluckerOptions>().morton = (variant & 4) != 0;
        PluckerAccel accel;
        accel.build(geometry.view(), options);
        for (std::size_t s = 0; s < sets.size(); ++s) {
            const Agreement agreement =
                compare_hits(sets[s].rays, expected[s], testing::trace_in_parallel(accel, sets[s].rays));
            std::printf("%s, %s: plucker balanced=%d stored_boxes=%d morton=%d vs bvh: %s\n", GetParam(),
                        sets[s].name.c_str(), options.group<PluckerOptions>().balanced,
                        options.group<PluckerOptions>().stored_boxes, options.group<PluckerOptions>().morton,
                        agreement.summary().c_str());
            EXPECT_EQ(agreement.mismatches, 0u) << "variant " << variant << ": " << agreement.summary();
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Meshes, PluckerStanford, testing::stanford_meshes(), testing::stanford_mesh_name);

}  // namespace
}  // namespace lancer
