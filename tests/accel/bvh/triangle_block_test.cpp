// The triangle block kernels (src/accel/bvh/triangle_block.hpp) against the scalar kernels they transcribe
// (core/intersect.hpp): every lane they decide, bit for bit, on adversarial triangles and rays, and the lanes
// they hand to the scalar kernel.
#include "accel/bvh/triangle_block.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <span>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/primitive_intersect.hpp"

namespace lancer {
namespace {

// Triangles that exercise the kernels' edge cases: random, on an integer grid (rays through their vertices
// and edges give exactly zero watertight edge functions), sharing an edge or copying the previous triangle
// (ties, resolved by index), with a repeated vertex, collinear, tiny, huge (overflowing products), or with a
// NaN.
std::vector<Triangle> adversarial_triangles(std::mt19937& rng, int count) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_int_distribution<int> grid(-2, 2), kind(0, 9);
    auto point = [&] { return Vec3f(unit(rng), unit(rng), unit(rng)); };
    auto grid_point = [&] {
        return Vec3f(static_cast<float>(grid(rng)), static_cast<float>(grid(rng)),
                     static_cast<float>(grid(rng)));
    };
    std::vector<Triangle> triangles = {{point(), point(), point()}};
    while (static_cast<int>(triangles.size()) < count) {
        const Triangle previous = triangles.back();
        Triangle tri{point(), point(), point()};
        switch (kind(rng)) {
            case 0:
                tri = {grid_point(), grid_point(), grid_point()};
                break;
            case 1:
                tri = {grid_point(), grid_point(), grid_point()};
                break;
            case 2:
                tri = {previous.v1, previous.v0, point()};
                break;
            case 3:
                tri = previous;
                break;
            case 4:
                tri.v1 = tri.v0;
                break;
            case 5:
                tri.v2 = tri.v0 + 2.0f * (tri.v1 - tri.v0);
                break;
            case 6:
                tri = {tri.v0, tri.v0 + 1e-7f * point(), tri.v0 + 1e-7f * point()};
                break;
            case 7:
                tri = {1e30f * point(), 1e30f * point(), 1e30f * point()};
                break;
            case 8:
                tri.v2.y = std::numeric_limits<float>::quiet_NaN();
                break;
            default:
                break;
        }
        triangles.push_back(tri);
    }
    return triangles;
}

// A ray aimed at a triangle's vertex, edge midpoint or interior, or axis-parallel from a grid point, or
// random; sometimes with a cut interval.
Ray adversarial_ray(std::mt19937& rng, const Triangle& target) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), positive(0.0f, 1.0f);
    std::uniform_int_distribution<int> grid(-3, 3), kind(0, 5), axis(0, 2);
    auto grid_point = [&] {
        return Vec3f(static_cast<float>(grid(rng)), static_cast<float>(grid(rng)),
                     static_cast<float>(grid(rng)));
    };
    Vec3f origin = 3.0f * Vec3f(unit(rng), unit(rng), unit(rng)), aim;
    switch (kind(rng)) {
        case 0:
            aim = target.v0;
            break;
        case 1:
            aim = 0.5f * (target.v0 + target.v1);
            break;
        case 2: {
            const float a = positive(rng), b = positive(rng) * (1.0f - a);
            aim = target.v0 + a * (target.v1 - target.v0) + b * (target.v2 - target.v0);
            break;
        }
        case 3: {
            origin = grid_point();
            aim = origin;
            aim[axis(rng)] += unit(rng) < 0.0f ? -1.0f : 1.0f;
            break;
        }
        default:
            aim = Vec3f(unit(rng), unit(rng), unit(rng));
            break;
    }
    Ray ray{origin, aim - origin, 0.0f, kInfinity};
    if (kind(rng) == 0) ray.tnear = positive(rng), ray.tfar = ray.tnear + positive(rng);
    return ray;
}

bool same_bits(float a, float b) {
    return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b);
}

struct KernelCheckCounts {
    std::size_t lane_hits = 0, scalar_lanes = 0, closest_hits = 0, occluded = 0;
};

// For random blocks of K primitives of a mixed scene (spheres among the triangles, padding at the end):
// every lane the block kernel decides agrees with the scalar test (hit or miss, and t, u, v bit for bit),
// intersect_block gives the scalar loop's closest hit (bit for bit, ties to the smaller index) from a random
// starting hit, and occludes_block the scalar loop's answer.
template <class TriangleTestT, int K>
void check_block_kernel(std::uint32_t seed, KernelCheckCounts& counts) {
    std::mt19937 rng(seed);
    const std::vector<Triangle> triangles = adversarial_triangles(rng, 400);
    const std::vector<Sphere> spheres = {{{0, 0, 0}, 0.5f, 0}, {{1, 0, 0}, 0.25f, 0}};
    const Geometry geometry{triangles, spheres};
    std::uniform_int_distribution<std::uint32_t> any_prim(0, static_cast<std::uint32_t>(geometry.size() - 1));
    std::uniform_int_distribution<std::uint32_t> any_triangle(
        0, static_cast<std::uint32_t>(triangles.size() - 1));
    std::uniform_int_distribution<int> lanes(1, K), choice(0, 9);
    for (int trial = 0; trial < 20000; ++trial) {
        // Mostly neighbours in the triangle list, so that shared edges and copies land in one block.
        std::vector<std::uint32_t> prims;
        const std::uint32_t start = any_triangle(rng);
        const int used = lanes(rng);
        for (int lane = 0; lane < used; ++lane) {
            const std::uint32_t neighbour = std::min<std::uint32_t>(
                start + static_cast<std::uint32_t>(lane), static_cast<std::uint32_t>(triangles.size() - 1));
            const std::uint32_t prim = choice(rng) == 0 ? any_prim(rng) : neighbour;
            if (std::find(prims.begin(), prims.end(), prim) == prims.end()) prims.push_back(prim);
        }
        std::shuffle(prims.begin(), prims.end(), rng);
        std::vector<TriangleBlock<K>> blocks;
        append_leaf_blocks(geometry, std::span<const std::uint32_t>(prims), blocks);
        ASSERT_EQ(blocks.size(), 1u);
        const TriangleBlock<K>& block = blocks[0];

        const Ray ray = adversarial_ray(rng, triangles[start]);
        if (!is_valid(ray)) continue;
        const PreparedRay<TriangleTestT> prepared(ray);
        const BlockRay<TriangleTestT, K> block_ray(prepared, geometry);

        BlockHits<K> hits;
        block_ray.kernel.test(block, ray.tnear, ray.tfar, hits);
        counts.scalar_lanes += static_cast<std::size_t>(std::popcount(hits.scalar_lanes));
        for (int lane = 0; lane < K; ++lane) {
            const bool kernel_hit = (hits.hit_lanes >> lane) & 1u;
            const bool is_triangle = lane < static_cast<int>(prims.size()) && prims[lane] < triangles.size();
            if (!is_triangle) {
                ASSERT_FALSE(kernel_hit) << "trial " << trial << ": a padding or sphere lane hit";
                continue;
            }
            if ((hits.scalar_lanes >> lane) & 1u) continue;
            TriangleHit expected;
            const bool scalar_hit = TriangleTestT::intersect(prepared.triangle_data, triangles[prims[lane]],
                                                             ray.tnear, ray.tfar, expected);
            ASSERT_EQ(kernel_hit, scalar_hit) << "trial " << trial << " lane " << lane;
            if (!kernel_hit) continue;
            ++counts.lane_hits;
            ASSERT_TRUE(same_bits(hits.t[lane], expected.t) && same_bits(hits.u[lane], expected.u) &&
                        same_bits(hits.v[lane], expected.v))
                << "trial " << trial << " lane " << lane;
        }

        Hit start_hit;
        if (choice(rng) < 3)
            start_hit = {4.0f * std::abs(static_cast<float>(choice(rng))) / 9.0f,
                         static_cast<std::int32_t>(any_prim(rng)), 0.25f, 0.5f};
        Hit expected = start_hit, actual = start_hit;
        for (const std::uint32_t prim : prims)
            intersect_primitive(geometry, prim, prepared, expected);
        intersect_block(geometry, block, block_ray, actual);
        ASSERT_EQ(actual.prim, expected.prim) << "trial " << trial;
        ASSERT_TRUE(same_bits(actual.t, expected.t) && same_bits(actual.u, expected.u) &&
                    same_bits(actual.v, expected.v))
            << "trial " << trial;
        counts.closest_hits += expected.prim != start_hit.prim;

        bool expected_occluded = false;
        for (const std::uint32_t prim : prims)
            expected_occluded = expected_occluded || occludes(geometry, prim, prepared);
        ASSERT_EQ(occludes_block(geometry, block, block_ray), expected_occluded) << "trial " << trial;
        counts.occluded += expected_occluded;
    }
}

template <class TriangleTestT>
void check_block_kernels(std::uint32_t seed) {
    KernelCheckCounts counts;
    check_block_kernel<TriangleTestT, 4>(seed, counts);
    check_block_kernel<TriangleTestT, 8>(seed + 1, counts);
    // Not a degenerate sample: many lanes hit, many closest hits change, and both tests hand many lanes to
    // their double fallback: the watertight test its zero and denormal edge functions (grid triangles,
    // repeated vertices; 34,989 with these seeds), Moller-Trumbore its grazing lanes and those within its
    // error bound of an edge (9,054; 47 grazing ones before fuzz finding 23).
    EXPECT_GT(counts.lane_hits, 6000u);
    EXPECT_GT(counts.closest_hits, 5000u);
    EXPECT_GT(counts.occluded, 5000u);
    EXPECT_GT(counts.scalar_lanes, 1000u);
}

TEST(TriangleBlock, MollerTrumboreBlockEqualsScalarTest) {
    check_block_kernels<MollerTrumbore>(11);
}

TEST(TriangleBlock, WatertightBlockEqualsScalarTest) {
    check_block_kernels<Watertight>(21);
}

// A lane whose ray lies on one edge's line (that edge function exactly 0, so uncertain) while the other two
// edge functions are certain and of opposite signs is a miss the vector kernel decides itself, as the
// scalar kernel's first test would, instead of handing it to the scalar kernel (docs/accel/bvh_wide.md,
// "Uncertain lanes that are misses"). A lane on an edge's line between two certain edge functions of one
// sign still goes to the scalar kernel, which decides the exact sign.
TEST(TriangleBlock, WatertightKernelKeepsCertainMisses) {
    const std::vector<Triangle> triangles = {
        {{1.0f, 0.0f, 0.0f}, {2.0f, 0.0f, 0.0f}, {1.5f, 1.0f, 0.0f}},    // the ray on v0 v1's line, beside it
        {{-1.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}}};  // the ray on the edge v0 v1 itself
    const Geometry geometry{triangles, {}};
    const Ray ray{{0.0f, 0.0f, -10.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, kInfinity};
    const PreparedRay<Watertight> prepared(ray);
    std::vector<TriangleBlock<8>> blocks;
    const std::uint32_t prims[] = {0, 1};
    append_leaf_blocks(geometry, std::span<const std::uint32_t>(prims), blocks);
    ASSERT_EQ(blocks.size(), 1u);
    const BlockRay<Watertight, 8> block_ray(prepared, geometry);
    BlockHits<8> hits;
    block_ray.kernel.test(blocks[0], ray.tnear, ray.tfar, hits);
    EXPECT_EQ(hits.scalar_lanes, 0b10u);  // the first lane decided here, the second by the scalar kernel
    EXPECT_EQ(hits.hit_lanes & 1u, 0u);
    TriangleHit scalar;
    EXPECT_FALSE(Watertight::intersect(prepared.triangle_data, triangles[0], ray.tnear, ray.tfar, scalar));
}

}  // namespace
}  // namespace lancer
