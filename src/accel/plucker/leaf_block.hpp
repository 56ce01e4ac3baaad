// The leaf test of the Plücker walks: a leaf's primitive copies gathered into the wide BVH's triangle blocks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>

#include "accel/bvh/triangle_block.hpp"
#include "accel/plucker/layout.hpp"
#include "accel/simd_float.hpp"

namespace lancer::plucker {

// A leaf's primitives are tested kLeafLanes at a time by the wide BVH's block kernel (bit for bit the scalar
// test's answers, docs/accel/bvh_wide.md).
constexpr int kLeafLanes = 8;
using LeafBlock = TriangleBlock<kLeafLanes>;

// The first min(count, kLeafLanes) primitives of a leaf copied into one block; a sphere's lane and the
// padding get NaN vertices, which the kernel rejects, the sphere then going through the scalar path.
inline void gather_block(const PluckerPrimitive* primitives, std::uint32_t count,
                         std::uint32_t triangle_count, LeafBlock& block) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
#if defined(__AVX2__)
    // Each present triangle's first 8 floats (v0, v1, v2.x, v2.y) as one row, transposed in registers into
    // the block's first 8 coordinate rows; v2.z and the indices lane by lane.
    static_assert(offsetof(PluckerPrimitive, triangle) == 0 && sizeof(Triangle) == 36);
    using Ops = simd::Avx2;
    Ops::Float rows[kLeafLanes], fields[kLeafLanes];
    alignas(32) float last[kLeafLanes];
    for (std::uint32_t lane = 0; lane < static_cast<std::uint32_t>(kLeafLanes); ++lane) {
        const bool present = lane < count;
        block.prim[lane] = present ? primitives[lane].prim : LeafBlock::kNoPrimitive;
        const bool is_triangle = present && primitives[lane].prim < triangle_count;
        rows[lane] = is_triangle ? _mm256_loadu_ps(&primitives[lane].triangle.v0.x) : Ops::broadcast(nan);
        last[lane] = is_triangle ? primitives[lane].triangle.v2.z : nan;
    }
    Ops::transpose8(rows, fields);
    for (int field = 0; field < 8; ++field)
        Ops::store(block.vertex[field / 3][field % 3], fields[field]);
    Ops::store(block.vertex[2][2], Ops::load(last));
#else
    for (std::uint32_t lane = 0; lane < static_cast<std::uint32_t>(kLeafLanes); ++lane) {
        const bool present = lane < count;
        block.prim[lane] = present ? primitives[lane].prim : LeafBlock::kNoPrimitive;
        const bool is_triangle = present && primitives[lane].prim < triangle_count;
        const Triangle& tri = primitives[is_triangle ? lane : 0].triangle;
        const Vec3f* corners[3] = {&tri.v0, &tri.v1, &tri.v2};
        for (int v = 0; v < 3; ++v) {
            for (int axis = 0; axis < 3; ++axis)
                block.vertex[v][axis][lane] = is_triangle ? (*corners[v])[axis] : nan;
        }
    }
#endif
}

// Calls test_block(block) for the blocks of the leaf whose record is `record`, in order, each gathered once,
// until it returns true (an occlusion found); returns whether it did.
template <class TestBlock>
inline bool for_each_leaf_block(const PluckerLayout& layout, const std::uint32_t* record,
                                TestBlock&& test_block) {
    const std::uint32_t count = record[kTriangleCount];
    const PluckerPrimitive* leaf = layout.primitives.data() + record[kTriangleOffset];
    for (std::uint32_t first = 0; first < count; first += kLeafLanes) {
        LeafBlock block;
        gather_block(leaf + first, count - first, layout.triangle_count, block);
        if (test_block(block)) return true;
    }
    return false;
}

// The ray as the block kernel takes it, made once per ray (or per ray and leaf in a packet's group).
template <class TriangleTestT>
[[nodiscard]] inline BlockRay<TriangleTestT, kLeafLanes> leaf_block_ray(
    const PreparedRay<TriangleTestT>& prepared, const Geometry& geometry) {
    return {prepared, geometry};
}

}  // namespace lancer::plucker
