// The Stanford meshes of ../shared/data/meshes, when present: every structure against the others on every
// ray of the canonical view (shared/bench/VIEWS.md, 1024 x 1024), of 10^6 random rays, and of rays through
// vertices and edges, axis-parallel rays and rays with tnear > 0 and finite tfar; brute force on a sample of
// each set. A sanitized build traces 1/testing::kSanitizedStride of each (ray_sets.hpp). Brute force on all 2
// x 10^6 rays of the dragon would take hours (1.7e12 triangle tests), so the chain is: brute force == bvh on
// the sample, then bvh == every other structure on every ray. The structures built on the binary BVH are
// tested again with spatial splits, with both triangle tests.
#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <map>
#include <numeric>

#include "accel/bvh/triangle_block.hpp"
#include "lancer/agreement.hpp"
#include "support/configurations.hpp"
#include "support/ray_sets.hpp"
#include "support/stanford_meshes.hpp"

namespace lancer {
namespace {

// Brute force eight triangles at a time: every ray against every primitive, in index order, through the
// triangle blocks of bvh8's leaves (accel/bvh/triangle_block.hpp), whose kernels the TriangleBlock tests
// prove bit-identical to the scalar ones, so the answers are the `brute` structure's, in a tenth of its time
// (docs/robustness.md, "CI time").
std::vector<Hit> brute_force_in_blocks(const Geometry& geometry, TriangleTest test,
                                       std::span<const Ray> rays) {
    std::vector<std::uint32_t> prims(geometry.size());
    std::iota(prims.begin(), prims.end(), 0u);
    std::vector<TriangleBlock<8>> blocks;
    append_leaf_blocks<8>(geometry, prims, blocks);
    std::vector<Hit> hits(rays.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), 16), [&](const auto& range) {
        intersect_each(test, rays.subspan(range.begin(), range.size()),
                       std::span(hits).subspan(range.begin(), range.size()), nullptr,
                       [&]<class TriangleTestT, bool>(const PreparedRay<TriangleTestT>& prepared, Hit& best,
                                                      TraversalCounters&) {
                           const BlockRay<TriangleTestT, 8> ray(prepared, geometry);
                           for (const TriangleBlock<8>& block : blocks)
                               intersect_block(geometry, block, ray, best);
                       });
    });
    return hits;
}

class StanfordMesh : public testing::StanfordMeshTest {};

TEST_P(StanfordMesh, EveryStructureAgreesOnTheCanonicalViewAndOnRandomRays) {
    const SceneGeometry& geometry = mesh();
    const Box3f bounds = geometry.view().bounds();

    std::vector<testing::RaySet> sets = {
        testing::canonical_view_rays(bounds), testing::random_rays(bounds, 1'000'000, 17),
        testing::vertex_and_edge_rays(geometry.view().triangles, 50'000, 18),
        testing::axis_parallel_rays(bounds, 50'000, 19), testing::clipped_rays(bounds, 50'000, 20)};
    for (testing::RaySet& set : sets)
        testing::keep_every(set, testing::kSanitizedStride);
    // The reference, bvh with its defaults, per triangle test and set; brute force agrees with it on an
    // evenly spread sample of each set: about 4e9 triangle tests per mesh and triangle test over all the
    // sets.
    const std::size_t sample_size =
        4'000'000'000 / testing::kSanitizedStride / geometry.view().size() / sets.size();
    std::map<TriangleTest, std::vector<std::vector<Hit>>> reference_hits;
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const char* test_name = test == TriangleTest::Watertight ? "watertight" : "moller";
        const std::unique_ptr<Accel> reference = make_accel("bvh");
        reference->build(geometry.view(), build_options(test));
        for (const testing::RaySet& set : sets) {
            const std::vector<Hit>& hits =
                reference_hits[test].emplace_back(testing::trace_in_parallel(*reference, set.rays));
            std::vector<Ray> sample;
            std::vector<Hit> sample_reference;
            for (std::size_t i = 0; i < set.rays.size();
                 i += std::max<std::size_t>(1, set.rays.size() / sample_size)) {
                sample.push_back(set.rays[i]);
                sample_reference.push_back(hits[i]);
            }
            const Agreement with_brute =
                compare_hits(sample, brute_force_in_blocks(geometry.view(), test, sample), sample_reference);
            std::printf("%s, %s, %s: bvh vs brute force on %zu sampled rays: %s\n", GetParam(),
                        set.name.c_str(), test_name, sample.size(), with_brute.summary().c_str());
            EXPECT_EQ(with_brute.mismatches, 0u) << test_name << ": " << with_brute.summary();
            EXPECT_GT(with_brute.hits, sample.size() / 20);
        }
    }

    // Every other structure on every ray (embree: see embree_test.cpp), with the Moller-Trumbore test; those
    // built on the binary BVH again with spatial splits, and bvh8_packet's AVX2 kernels beside AVX-512, with
    // both triangle tests.
    std::vector<std::string_view> names = accel_names();
    std::erase_if(names, [](std::string_view name) { return name == "brute" || name.starts_with("embree"); });
    for (const testing::Configuration& configuration : testing::agreement_configurations(names)) {
        if (configuration.name == "bvh" && !configuration.spatial_splits) continue;  // the reference
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            const bool variant = configuration.spatial_splits || configuration.isa != SimdIsa::Auto;
            if (test == TriangleTest::Watertight && !variant) continue;
            const char* test_name = test == TriangleTest::Watertight ? "watertight" : "moller";
            const std::unique_ptr<Accel> accel = make_accel(configuration.name);
            accel->build(geometry.view(), configuration.options(test));
            for (std::size_t k = 0; k < sets.size(); ++k) {
                const testing::RaySet& set = sets[k];
                const Agreement agreement = compare_hits(set.rays, reference_hits[test][k],
                                                         testing::trace_in_parallel(*accel, set.rays));
                std::printf("%s, %s, %s: %s vs bvh on every ray: %s\n", GetParam(), set.name.c_str(),
                            test_name, configuration.label().c_str(), agreement.summary().c_str());
                EXPECT_EQ(agreement.mismatches, 0u) << configuration.label() << ", " << set.name << ", "
                                                    << test_name << ": " << agreement.summary();
            }
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Meshes, StanfordMesh, testing::stanford_meshes(), testing::stanford_mesh_name);

}  // namespace
}  // namespace lancer
