// GroupedBatch: a level's rays reach the structure grouped (by light, by kind), in shading order within a
// group, and every answer comes back to the ray it belongs to.
#include "render/grouped_batch.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

namespace lancer {
namespace {

TEST(GroupedBatch, TracesGroupByGroupAndAnswersInShadingOrder) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
    GroupedBatch<std::uint8_t> batch;  // one batch for every round: its buffers are reused
    for (const std::size_t group_count : {1u, 2u, 5u}) {
        for (const std::size_t size : {0u, 1u, 7u, 1000u}) {
            std::vector<Ray> rays;
            std::vector<std::uint32_t> group_of_ray;
            for (std::size_t i = 0; i < size; ++i) {
                // The ray's index in its origin, to recognise it in the batch the structure is handed.
                rays.push_back(
                    {{static_cast<float>(i), coordinate(rng), coordinate(rng)}, {0, 0, 1}, 0.0f, 1.0f});
                group_of_ray.push_back(static_cast<std::uint32_t>(rng() % group_count));
            }
            std::vector<std::size_t> handed;
            int calls = 0;
            std::vector<std::uint8_t> blocked;
            batch.trace(rays, group_of_ray, group_count, blocked,
                        [&](std::span<const Ray> traced, std::span<std::uint8_t> traced_blocked) {
                            ++calls;
                            ASSERT_EQ(traced.size(), traced_blocked.size());
                            for (std::size_t k = 0; k < traced.size(); ++k) {
                                handed.push_back(static_cast<std::size_t>(traced[k].origin.x));
                                traced_blocked[k] = traced[k].origin.y > 0.0f ? 1 : 0;
                            }
                        });
            EXPECT_EQ(calls, 1);
            ASSERT_EQ(handed.size(), size);
            ASSERT_EQ(blocked.size(), size);
            for (std::size_t i = 0; i < size; ++i)
                EXPECT_EQ(blocked[i], rays[i].origin.y > 0.0f ? 1 : 0) << "ray " << i;
            // Grouped by light, and in shading order within a light.
            for (std::size_t k = 1; k < handed.size(); ++k) {
                const std::uint32_t before = group_of_ray[handed[k - 1]], after = group_of_ray[handed[k]];
                EXPECT_TRUE(before < after || (before == after && handed[k - 1] < handed[k]))
                    << group_count << " groups, position " << k;
            }
        }
    }
}

}  // namespace
}  // namespace lancer
