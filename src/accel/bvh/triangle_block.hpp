// Triangles in SIMD blocks: the leaves of the wide BVH store their primitives K at a time, vertices
// pre-gathered in structure of arrays, and test a whole block against a ray with one vector Moller-Trumbore
// or one vector watertight test (Embree's Triangle4v / Triangle8v; Wald, Benthin & Boulos, "Getting Rid of
// Packets", RT 2008, section 4). docs/accel/bvh_wide.md has the design note.
//
// Bit-identical to the scalar kernels of core/intersect.hpp: every lane performs the same fp32 operations in
// the same order (none contracted into a fused multiply-add, -ffp-contract=off; the watertight edge functions
// fuse explicitly in both, difference_of_products), with the same ill-conditioned band and the same
// acceptance tests; lanes whose watertight edge functions fall within their error bound
// (Watertight::kEdgeSlack), or whose numerator falls below Watertight::kSmallNumerator, are handed to the
// scalar test, which decides them exactly or in double. The
// closest lane is chosen with closer(), ties to the smaller index.
#pragma once

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "accel/primitive_intersect.hpp"
#include "accel/simd_float.hpp"
#include "core/intersect.hpp"

namespace lancer {

// One block of K primitives of a leaf: 36 K + 4 K bytes (160 for K = 4, 320 for K = 8), a multiple of the
// vector size, so consecutive blocks stay aligned. A lane that holds no triangle (a padding lane, or a
// sphere in a mixed scene, tested by the scalar path) has NaN vertices, which every vector acceptance test
// rejects (NaN compares false), and never reaches the double fallback (NaN == 0 is false).
template <int K>
struct alignas(K * 4) TriangleBlock {
    static constexpr std::uint32_t kNoPrimitive = std::numeric_limits<std::uint32_t>::max();
    // 36 K bytes: vertex[v0 | v1 | v2][axis][lane], as in the Triangle.
    float vertex[3][3][K];
    // 4 K bytes: global primitive index of each lane; kNoPrimitive for padding.
    std::uint32_t prim[K];

    // Left uninitialised, as a local block is: every writer fills all of a block's lanes, and a vector of
    // blocks sized for a build (the dragon's 47 MB) would otherwise be zeroed first, serially. Not
    // `= default`, which value-initialisation zeroes.
    TriangleBlock() {}  // NOLINT(modernize-use-equals-default)

    [[nodiscard]] Triangle triangle(int lane) const {
        auto corner = [&](int v) {
            return Vec3f(vertex[v][0][lane], vertex[v][1][lane], vertex[v][2][lane]);
        };
        return {corner(0), corner(1), corner(2)};
    }
};
static_assert(sizeof(TriangleBlock<4>) == 160 && sizeof(TriangleBlock<8>) == 320);

// Writes `prim`'s vertices into `lane` of `block`: a triangle's corners, NaN for a sphere or padding
// (kNoPrimitive).
template <int K>
void write_block_lane(const Geometry& geometry, std::uint32_t prim, int lane, TriangleBlock<K>& block) {
    block.prim[lane] = prim;
    const bool is_triangle = prim < geometry.triangles.size();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const Triangle tri = is_triangle ? geometry.triangles[prim] : Triangle{};
    for (int axis = 0; axis < 3; ++axis) {
        block.vertex[0][axis][lane] = is_triangle ? tri.v0[axis] : nan;
        block.vertex[1][axis][lane] = is_triangle ? tri.v1[axis] : nan;
        block.vertex[2][axis][lane] = is_triangle ? tri.v2[axis] : nan;
    }
}

// Writes the blocks of one leaf from `blocks` on: its primitives in order, K per block, the last block
// padded.
template <int K>
void write_leaf_blocks(const Geometry& geometry, std::span<const std::uint32_t> prims,
                       TriangleBlock<K>* blocks) {
    for (std::size_t first = 0; first < prims.size(); first += K) {
        TriangleBlock<K>& block = *blocks++;
        for (int lane = 0; lane < K; ++lane) {
            const std::size_t i = first + static_cast<std::size_t>(lane);
            write_block_lane(geometry, i < prims.size() ? prims[i] : TriangleBlock<K>::kNoPrimitive, lane,
                             block);
        }
    }
}

// The same blocks appended to `blocks`.
template <int K>
void append_leaf_blocks(const Geometry& geometry, std::span<const std::uint32_t> prims,
                        std::vector<TriangleBlock<K>>& blocks) {
    const std::size_t first = blocks.size();
    blocks.resize(first + (prims.size() + K - 1) / K);
    write_leaf_blocks(geometry, prims, blocks.data() + first);
}

[[nodiscard]] constexpr std::uint32_t block_count(std::uint32_t prim_count, int lanes) {
    return (prim_count + static_cast<std::uint32_t>(lanes) - 1) / static_cast<std::uint32_t>(lanes);
}

// What a block test returns: the lanes hit in [tnear, tfar] with their t, u, v, and the lanes the scalar
// test must decide (a watertight edge function within its error bound, a Moller-Trumbore ray near an edge).
template <int K>
struct BlockHits {
    alignas(32) float t[K];
    alignas(32) float u[K];
    alignas(32) float v[K];
    unsigned hit_lanes = 0;
    unsigned scalar_lanes = 0;
};

// The vector kernels, one per triangle test, on a ray broadcast once (BlockRay below).
namespace block_detail {

#if defined(__AVX2__) || defined(__SSE4_1__)
template <class Ops>
struct Vec3v {
    typename Ops::Float x, y, z;
};

template <class Ops, int K>
[[nodiscard]] inline Vec3v<Ops> load_vertex(const TriangleBlock<K>& block, int v) {
    return {Ops::load(block.vertex[v][0]), Ops::load(block.vertex[v][1]), Ops::load(block.vertex[v][2])};
}

template <class Ops>
[[nodiscard]] inline Vec3v<Ops> sub(const Vec3v<Ops>& a, const Vec3v<Ops>& b) {
    return {Ops::sub(a.x, b.x), Ops::sub(a.y, b.y), Ops::sub(a.z, b.z)};
}
// dot() and cross() of lancer/vec.hpp, term for term.
template <class Ops>
[[nodiscard]] inline typename Ops::Float dot(const Vec3v<Ops>& a, const Vec3v<Ops>& b) {
    return Ops::add(Ops::add(Ops::mul(a.x, b.x), Ops::mul(a.y, b.y)), Ops::mul(a.z, b.z));
}
template <class Ops>
[[nodiscard]] inline Vec3v<Ops> cross(const Vec3v<Ops>& a, const Vec3v<Ops>& b) {
    return {Ops::sub(Ops::mul(a.y, b.z), Ops::mul(a.z, b.y)),
            Ops::sub(Ops::mul(a.z, b.x), Ops::mul(a.x, b.z)),
            Ops::sub(Ops::mul(a.x, b.y), Ops::mul(a.y, b.x))};
}
// max_component(abs(e)). std::max and maxps differ only on NaN, and a NaN edge component makes det NaN
// (every product with it is NaN), which the band test rejects either way.
template <class Ops>
[[nodiscard]] inline typename Ops::Float max_abs_component(const Vec3v<Ops>& a) {
    return Ops::max(Ops::abs(a.x), Ops::max(Ops::abs(a.y), Ops::abs(a.z)));
}

// What a lane kernel returns: every lane's t, u and v, the lanes hit in [tnear, tfar] and the lanes the
// scalar test must decide, in double.
template <class Ops>
struct LaneHits {
    typename Ops::Float t, u, v;
    unsigned hit_lanes = 0;
    unsigned scalar_lanes = 0;
};

// What Moller-Trumbore computes from the triangle alone, in the scalar kernel's operations. The packet
// test broadcasts one triangle to all its lanes, so it makes these once per block of triangles instead of
// once per (triangle, group of rays): a sixth of the kernel's operations.
template <class Ops>
struct MollerTrumboreEdges {
    Vec3v<Ops> v0, e1, e2;
    typename Ops::Float e1_scale, e2_scale;  // max_component(abs(e1)), max_component(abs(e2))
};
template <class Ops>
[[nodiscard]] inline MollerTrumboreEdges<Ops> moller_trumbore_edges(const Vec3v<Ops>& v0,
                                                                    const Vec3v<Ops>& v1,
                                                                    const Vec3v<Ops>& v2) {
    const Vec3v<Ops> e1 = sub(v1, v0), e2 = sub(v2, v0);
    return {v0, e1, e2, max_abs_component(e1), max_abs_component(e2)};
}

// MollerTrumbore::intersect on every lane: lane i tests ray i against triangle i. The triangle-SIMD block
// test broadcasts one ray against a block's triangles; the packet test (bvh8_packet.cpp) broadcasts one
// triangle against a packet's rays: both call this, so that one source holds the kernel. A lane that
// passes the widened float u and v tests but is grazing or within their error bound of an edge is left to
// the scalar kernel, which decides it in double.
template <class Ops>
struct MollerTrumboreLanes {
    using Float = typename Ops::Float;
    Vec3v<Ops> origin, direction;
    Float band_scale;   // kIllConditioned * direction_scale, the first product of the band
    Float slack_scale;  // kRoundingSlack * direction_scale, the first product of the slack

    // The ray data of each lane from its direction_scale (MollerTrumbore::RayData).
    MollerTrumboreLanes(const Vec3v<Ops>& ray_origin, const Vec3v<Ops>& ray_direction, Float direction_scale)
        : origin(ray_origin),
          direction(ray_direction),
          band_scale(Ops::mul(Ops::broadcast(MollerTrumbore::kIllConditioned), direction_scale)),
          slack_scale(Ops::mul(Ops::broadcast(MollerTrumbore::kRoundingSlack), direction_scale)) {}

    [[nodiscard]] LaneHits<Ops> test(const Vec3v<Ops>& v0, const Vec3v<Ops>& v1, const Vec3v<Ops>& v2,
                                     Float tnear, Float tfar) const {
        return test(moller_trumbore_edges(v0, v1, v2), tnear, tfar);
    }

    // Always inlined: GCC kept the AVX2 compilation's copy out of line, and its callers built the edges in
    // memory for the call (docs/accel/stream.md, "Where a shadow ray's instructions go").
    [[nodiscard, gnu::always_inline]] LaneHits<Ops> test(const MollerTrumboreEdges<Ops>& triangle,
                                                         Float tnear, Float tfar) const {
        const Vec3v<Ops>&v0 = triangle.v0, &e1 = triangle.e1, &e2 = triangle.e2;
        const Float e1_scale = triangle.e1_scale, e2_scale = triangle.e2_scale;
        const Vec3v<Ops> p = cross(direction, e2);
        const Float det = dot(p, e1);
        const Float abs_det = Ops::abs(det);
        const Float band = Ops::mul(Ops::mul(band_scale, e1_scale), e2_scale);
        auto accept =
            Ops::mask_and(Ops::greater(abs_det, band), Ops::less(abs_det, Ops::broadcast(kInfinity)));
        const Float inv_det = Ops::div(Ops::broadcast(1.0f), det);
        const Vec3v<Ops> to_origin = sub(origin, v0);
        const auto grazing =
            Ops::less_equal(abs_det, Ops::mul(band, Ops::broadcast(MollerTrumbore::kGrazingScale)));
        const Float slack = Ops::mul(
            Ops::mul(slack_scale, Ops::add(Ops::add(max_abs_component(to_origin), e1_scale), e2_scale)),
            Ops::abs(inv_det));
        const Float slack_u = Ops::mul(slack, e2_scale), slack_v = Ops::mul(slack, e1_scale);
        const Float u = Ops::mul(dot(to_origin, p), inv_det);
        const Float zero = Ops::broadcast(0.0f), one = Ops::broadcast(1.0f);
        accept = Ops::mask_and(accept, Ops::mask_and(Ops::greater_equal(u, Ops::sub(zero, slack_u)),
                                                     Ops::less_equal(u, Ops::add(one, slack_u))));
        const Vec3v<Ops> q = cross(to_origin, e1);
        const Float v = Ops::mul(dot(direction, q), inv_det);
        accept = Ops::mask_and(
            accept,
            Ops::mask_and(Ops::greater_equal(v, Ops::sub(zero, slack_v)),
                          Ops::less_equal(Ops::add(u, v), Ops::add(one, Ops::add(slack_u, slack_v)))));
        const auto certain =
            Ops::mask_and(Ops::mask_and(Ops::greater_equal(u, slack_u), Ops::greater_equal(v, slack_v)),
                          Ops::less_equal(Ops::add(u, v), Ops::sub(one, Ops::add(slack_u, slack_v))));
        const unsigned scalar_lanes = Ops::bits(accept) & (Ops::bits(grazing) | ~Ops::bits(certain));
        const Float t = Ops::mul(dot(e2, q), inv_det);
        accept = Ops::mask_and(
            accept, Ops::mask_and(Ops::mask_and(Ops::greater_equal(t, tnear), Ops::less_equal(t, tfar)),
                                  Ops::less(t, Ops::broadcast(kInfinity))));
        return {t, u, v, Ops::bits(accept) & ~scalar_lanes, scalar_lanes};
    }
};

// Watertight::intersect on every lane, lane i testing ray i against triangle i, for rays that share one
// axis permutation (kx, ky, kz): the caller hands each vertex over as (v[kx], v[ky], v[kz]).
template <class Ops>
struct WatertightLanes {
    using Float = typename Ops::Float;
    Float origin_x, origin_y, origin_z;  // the origin's kx, ky, kz components
    Float shear_x, shear_y, shear_z;

    // A vertex relative to the origin: (x, y) sheared into ray space, z the unsheared a[kz].
    [[nodiscard]] Vec3v<Ops> sheared(const Vec3v<Ops>& vertex) const {
        const Float z = Ops::sub(vertex.z, origin_z);
        return {Ops::sub(Ops::sub(vertex.x, origin_x), Ops::mul(shear_x, z)),
                Ops::sub(Ops::sub(vertex.y, origin_y), Ops::mul(shear_y, z)), z};
    }

    // The test runs to its end on every lane: whether a group's lanes all miss is data the predictor cannot
    // learn, and an exit before the division on it cost the packets more than the division it saved
    // (docs/accel/packets.md, "The watertight kernel without an early exit"). kUncertainOften: the lanes
    // are rays that meet small triangles from afar, a camera packet's on a fine mesh, where many lanes are
    // uncertain and a branch on whether any is was mispredicted (docs/accel/packets.md, "Uncertain lanes
    // without a branch").
    template <bool kUncertainOften = false>
    [[nodiscard]] LaneHits<Ops> test(const Vec3v<Ops>& v0, const Vec3v<Ops>& v1, const Vec3v<Ops>& v2,
                                     Float tnear, Float tfar) const {
        const Vec3v<Ops> a = sheared(v0), b = sheared(v1), c = sheared(v2);
        const Float w0 = Ops::difference_of_products(b.x, c.y, b.y, c.x);
        const Float w1 = Ops::difference_of_products(c.x, a.y, c.y, a.x);
        const Float w2 = Ops::difference_of_products(a.x, b.y, a.y, b.x);
        // Edge functions within Watertight::kEdgeSlack's bound, zero and denormal ones among them, and small
        // numerators are the scalar kernel's, which decides their signs exactly (core/intersect.hpp). The
        // bound as Watertight::edge_slack computes it; a NaN lane's (padding) compares false.
        const Float planar = Ops::max(Ops::max(Ops::max_magnitude(a.x, a.y), Ops::max_magnitude(b.x, b.y)),
                                      Ops::max_magnitude(c.x, c.y));
        const Float depth = Ops::max(Ops::max_magnitude(a.z, b.z), Ops::abs(c.z));
        const Float slack = Ops::max(
            Ops::mul(Ops::mul(Ops::add(planar, depth), planar), Ops::broadcast(Watertight::kEdgeSlack)),
            Ops::broadcast(std::numeric_limits<float>::min()));
        unsigned uncertain =
            Ops::bits(Ops::less_equal(Ops::min(Ops::min(Ops::abs(w0), Ops::abs(w1)), Ops::abs(w2)), slack));
        // Of those, a lane with two certain edge functions of opposite signs is a miss, which the scalar
        // kernel decides before any exact sign: it stays here. Small triangles seen from afar make many
        // uncertain lanes, most of them such misses (docs/accel/bvh_wide.md, "Uncertain lanes that are
        // misses").
        if (kUncertainOften || uncertain != 0) uncertain &= ~certain_misses(w0, w1, w2, slack);
        // Edge functions of both signs: a miss. Where all three are certain (the lanes not handed to the
        // scalar kernel), that is a sign bit that differs between them, read from w0 ^ w1 | w0 ^ w2 (three
        // operations where the compares took eleven). Three certain edge functions of one sign, the only
        // lanes left: det is not zero.
        const unsigned rejected = Ops::sign_bits(Ops::bit_or(Ops::bit_xor(w0, w1), Ops::bit_xor(w0, w2)));
        const Float det = Ops::add(Ops::add(w0, w1), w2);
        const Float az = Ops::mul(shear_z, a.z), bz = Ops::mul(shear_z, b.z), cz = Ops::mul(shear_z, c.z);
        const Float inv_det = Ops::div(Ops::broadcast(1.0f), det);
        const Float numerator = Ops::add(Ops::add(Ops::mul(w0, az), Ops::mul(w1, bz)), Ops::mul(w2, cz));
        const Float t = Ops::mul(numerator, inv_det);
        const auto t_accepted =
            Ops::mask_and(Ops::mask_and(Ops::greater_equal(t, tnear), Ops::less_equal(t, tfar)),
                          Ops::less(t, Ops::broadcast(kInfinity)));
        // As in the scalar kernel, a small numerator matters only once the signs have accepted the lane: rays
        // from a triangle's plane (T near 0) would otherwise send every lane they miss to the scalar path.
        const unsigned scalar_lanes =
            uncertain |
            (Ops::bits(Ops::less(Ops::abs(numerator), Ops::broadcast(Watertight::kSmallNumerator))) &
             ~rejected);
        return {t, Ops::mul(w1, inv_det), Ops::mul(w2, inv_det),
                Ops::bits(t_accepted) & ~rejected & ~scalar_lanes, scalar_lanes};
    }

  private:
    // The lanes where two edge functions are certain (beyond `slack`) and of opposite signs: misses by
    // Watertight::intersect's first test. Some edge function is beyond +slack exactly when the largest is,
    // and beyond -slack when the least is (with a finite slack the edge functions are not NaN; an infinite
    // or NaN slack makes no lane certain either way).
    [[nodiscard]] static unsigned certain_misses(Float w0, Float w1, Float w2, Float slack) {
        const Float highest = Ops::max(Ops::max(w0, w1), w2), lowest = Ops::min(Ops::min(w0, w1), w2);
        return Ops::bits(Ops::mask_and(Ops::greater(highest, slack),
                                       Ops::less(lowest, Ops::bit_xor(slack, Ops::broadcast(-0.0f)))));
    }
};

template <class Ops, int K>
inline void store_hits(const LaneHits<Ops>& lanes, BlockHits<K>& out) {
    out.hit_lanes = lanes.hit_lanes, out.scalar_lanes = lanes.scalar_lanes;
    Ops::store(out.t, lanes.t), Ops::store(out.u, lanes.u), Ops::store(out.v, lanes.v);
}

// MollerTrumbore::intersect of one ray against the K triangles of a block.
template <class Ops>
struct MollerTrumboreBlock {
    MollerTrumboreLanes<Ops> lanes;

    explicit MollerTrumboreBlock(const MollerTrumbore::RayData& ray)
        : lanes({Ops::broadcast(ray.origin.x), Ops::broadcast(ray.origin.y), Ops::broadcast(ray.origin.z)},
                {Ops::broadcast(ray.direction.x), Ops::broadcast(ray.direction.y),
                 Ops::broadcast(ray.direction.z)},
                Ops::broadcast(ray.direction_scale)) {}

    // The kernel of a ray of the same direction from `origin`: the constructor's broadcast of the origin
    // alone, for callers whose rays share their direction (GeometryQueries::count_crossings).
    void set_origin(const Vec3f& origin) {
        lanes.origin = {Ops::broadcast(origin.x), Ops::broadcast(origin.y), Ops::broadcast(origin.z)};
    }

    template <int K>
    [[gnu::always_inline]] void test(const TriangleBlock<K>& block, float tnear, float tfar,
                                     BlockHits<K>& out) const {
        store_hits(lanes.test(load_vertex<Ops>(block, 0), load_vertex<Ops>(block, 1),
                              load_vertex<Ops>(block, 2), Ops::broadcast(tnear), Ops::broadcast(tfar)),
                   out);
    }
};

// Watertight::intersect of one ray against the K triangles of a block. The ray's axis permutation is the
// same for every lane, so v[kx] is the load of the kx row of the block.
template <class Ops>
struct WatertightBlock {
    WatertightLanes<Ops> lanes;
    int kx, ky, kz;

    explicit WatertightBlock(const Watertight::RayData& ray)
        : lanes{Ops::broadcast(as_array(ray.origin)[ray.kx]),
                Ops::broadcast(as_array(ray.origin)[ray.ky]),
                Ops::broadcast(as_array(ray.origin)[ray.kz]),
                Ops::broadcast(ray.shear_x),
                Ops::broadcast(ray.shear_y),
                Ops::broadcast(ray.shear_z)},
          kx(ray.kx),
          ky(ray.ky),
          kz(ray.kz) {}

    // The kernel of a ray of the same direction from `origin`: the constructor's broadcasts of the origin
    // alone (the permutation and the shear depend on the direction only).
    void set_origin(const Vec3f& origin) {
        const std::array<float, 3> o = as_array(origin);
        lanes.origin_x = Ops::broadcast(o[kx]), lanes.origin_y = Ops::broadcast(o[ky]),
        lanes.origin_z = Ops::broadcast(o[kz]);
    }

    template <int K>
    [[nodiscard]] Vec3v<Ops> permuted(const TriangleBlock<K>& block, int v) const {
        return {Ops::load(block.vertex[v][kx]), Ops::load(block.vertex[v][ky]),
                Ops::load(block.vertex[v][kz])};
    }

    // Always inlined, as MollerTrumboreBlock's: the walks that call it once a block (bvh8's, the ray
    // streams') are where it runs, and GCC's budget left it out of line in the ray streams' walk.
    template <int K>
    [[gnu::always_inline]] void test(const TriangleBlock<K>& block, float tnear, float tfar,
                                     BlockHits<K>& out) const {
        store_hits(lanes.test(permuted(block, 0), permuted(block, 1), permuted(block, 2),
                              Ops::broadcast(tnear), Ops::broadcast(tfar)),
                   out);
    }
};
#endif

// Without SSE4.1 / AVX2: the scalar kernel lane by lane, on the block's copy of the vertices.
template <class TriangleTestT>
struct ScalarBlock {
    typename TriangleTestT::RayData ray;

    explicit ScalarBlock(const typename TriangleTestT::RayData& data) : ray(data) {}

    void set_origin(const Vec3f& origin) { ray.origin = origin; }

    template <int K>
    void test(const TriangleBlock<K>& block, float tnear, float tfar, BlockHits<K>& out) const {
        out.hit_lanes = 0, out.scalar_lanes = 0;
        for (int lane = 0; lane < K; ++lane) {
            TriangleHit hit;
            if (!TriangleTestT::intersect(ray, block.triangle(lane), tnear, tfar, hit)) continue;
            out.hit_lanes |= 1u << lane;
            out.t[lane] = hit.t, out.u[lane] = hit.u, out.v[lane] = hit.v;
        }
    }
};

template <class TriangleTestT, class Ops>
struct VectorKernel;
#if defined(__AVX2__) || defined(__SSE4_1__)
template <class Ops>
struct VectorKernel<MollerTrumbore, Ops> {
    using type = MollerTrumboreBlock<Ops>;
};
template <class Ops>
struct VectorKernel<Watertight, Ops> {
    using type = WatertightBlock<Ops>;
};
#endif

}  // namespace block_detail

// The block kernel of a triangle test for K lanes: SSE for 4, AVX2 for 8 where the compiler targets them,
// the scalar kernel lane by lane otherwise. Same hits, t, u and v in every case.
template <class TriangleTestT, int K>
struct BlockKernelFor {
    using type = block_detail::ScalarBlock<TriangleTestT>;
};
#if defined(__SSE4_1__)
template <class TriangleTestT>
struct BlockKernelFor<TriangleTestT, 4> {
    using type = typename block_detail::VectorKernel<TriangleTestT, simd::Sse4>::type;
};
#endif
#if defined(__AVX2__)
template <class TriangleTestT>
struct BlockKernelFor<TriangleTestT, 8> {
    using type = typename block_detail::VectorKernel<TriangleTestT, simd::Avx2>::type;
};
#endif
template <class TriangleTestT, int K>
using BlockKernel = typename BlockKernelFor<TriangleTestT, K>::type;

// A ray prepared for the scalar kernels and broadcast for the block kernel, once per ray.
template <class TriangleTestT, int K>
struct BlockRay {
    const PreparedRay<TriangleTestT>& prepared;
    BlockKernel<TriangleTestT, K> kernel;
    bool has_spheres;

    BlockRay(const PreparedRay<TriangleTestT>& p, const Geometry& geometry)
        : prepared(p), kernel(p.triangle_data), has_spheres(!geometry.spheres.empty()) {}
};

// The lanes of `block` that the scalar path tests: spheres (in mixed scenes) and the kernel's scalar lanes.
template <int K>
[[nodiscard]] inline unsigned scalar_lanes(const TriangleBlock<K>& block, const Geometry& geometry,
                                           bool has_spheres, unsigned kernel_scalar_lanes) {
    unsigned lanes = kernel_scalar_lanes;
    if (has_spheres) {
        for (int lane = 0; lane < K; ++lane) {
            if (block.prim[lane] >= geometry.triangles.size() &&
                block.prim[lane] != TriangleBlock<K>::kNoPrimitive)
                lanes |= 1u << lane;
        }
    }
    return lanes;
}

// intersect_primitive on every lane of a block: the closest hit in [tnear, best t] (ties to the smaller
// index, closer()) overwrites `best`. The lanes are tested against the same tfar; taking them through
// closer() in turn gives the answer of the scalar loop, whose shrinking tfar only drops lanes closer()
// rejects anyway.
template <class TriangleTestT, int K>
inline void intersect_block(const Geometry& geometry, const TriangleBlock<K>& block,
                            const BlockRay<TriangleTestT, K>& ray, Hit& best) {
    BlockHits<K> hits;
    ray.kernel.test(block, ray.prepared.ray.tnear, best.hit() ? best.t : ray.prepared.ray.tfar, hits);
    for (unsigned lanes = hits.hit_lanes; lanes != 0; lanes &= lanes - 1) {
        const int lane = std::countr_zero(lanes);
        const auto prim = static_cast<std::int32_t>(block.prim[lane]);
        if (closer(hits.t[lane], prim, best)) best = {hits.t[lane], prim, hits.u[lane], hits.v[lane]};
    }
    for (unsigned lanes = scalar_lanes(block, geometry, ray.has_spheres, hits.scalar_lanes); lanes != 0;
         lanes &= lanes - 1)
        intersect_primitive(geometry, block.prim[std::countr_zero(lanes)], ray.prepared, best);
}

// Every hit of the ray on a block, by on_hit(hit), in lane order: the kernel's lanes in [tnear, tfar], then
// the scalar test's (spheres and the kernel's uncertain lanes), as intersect_primitive gives them.
template <class TriangleTestT, int K, class OnHit>
inline void each_block_hit(const Geometry& geometry, const TriangleBlock<K>& block,
                           const BlockRay<TriangleTestT, K>& ray, OnHit&& on_hit) {
    const Ray& r = ray.prepared.ray;
    BlockHits<K> found;
    ray.kernel.test(block, r.tnear, r.tfar, found);
    for (unsigned lanes = found.hit_lanes; lanes != 0; lanes &= lanes - 1) {
        const int lane = std::countr_zero(lanes);
        on_hit(Hit{found.t[lane], static_cast<std::int32_t>(block.prim[lane]), found.u[lane], found.v[lane]});
    }
    for (unsigned lanes = scalar_lanes(block, geometry, ray.has_spheres, found.scalar_lanes); lanes != 0;
         lanes &= lanes - 1) {
        Hit hit;
        if (intersect_primitive(geometry, block.prim[std::countr_zero(lanes)], ray.prepared, hit))
            on_hit(hit);
    }
}

// occludes on every lane of a block: any hit in [tnear, tfar].
template <class TriangleTestT, int K>
[[nodiscard]] inline bool occludes_block(const Geometry& geometry, const TriangleBlock<K>& block,
                                         const BlockRay<TriangleTestT, K>& ray) {
    BlockHits<K> hits;
    ray.kernel.test(block, ray.prepared.ray.tnear, ray.prepared.ray.tfar, hits);
    if (hits.hit_lanes != 0) return true;
    for (unsigned lanes = scalar_lanes(block, geometry, ray.has_spheres, hits.scalar_lanes); lanes != 0;
         lanes &= lanes - 1) {
        if (occludes(geometry, block.prim[std::countr_zero(lanes)], ray.prepared)) return true;
    }
    return false;
}

}  // namespace lancer
