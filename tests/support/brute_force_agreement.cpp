#include "brute_force_agreement.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "lancer/agreement.hpp"

namespace lancer::testing {

void expect_brute_force_answers(const Accel& accel, const Geometry& geometry, TriangleTest test,
                                std::span<const Ray> rays, std::size_t min_hits) {
    const std::unique_ptr<Accel> brute = make_accel("brute");
    brute->build(geometry, build_options(test));
    std::vector<Hit> expected(rays.size()), hits(rays.size());
    std::vector<std::uint8_t> occluded(rays.size());
    brute->intersect(rays, expected);
    accel.intersect(rays, hits);
    accel.occluded(rays, occluded);
    const Agreement closest = compare_hits(rays, expected, hits);
    EXPECT_EQ(closest.mismatches, 0u) << closest.summary();
    EXPECT_GE(closest.hits, min_hits);
    const Agreement any = compare_occlusion(rays, expected, occluded);
    EXPECT_EQ(any.mismatches, 0u) << any.summary();
}

}  // namespace lancer::testing
