// The leaf tests of bvh8_packet's kernel: a leaf's triangles against the rays of the packet that reached it,
// a group of rays at a time, by one of two strategies, each triangle broadcast to the group's lanes
// (test_group) or each ray against a whole block (test_rays), and spheres and uncertain lanes through the
// scalar test. Private to the kernel's source (bvh8_packet_rays.hpp says why the anonymous namespace).
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/bvh8_packet_node_test.hpp"
#include "accel/bvh/bvh8_packet_rays.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/triangle_block.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/simd_float.hpp"
#include "core/isa_namespace.hpp"

#if defined(__AVX2__)
namespace lancer {
inline namespace LANCER_ISA_NAMESPACE {
namespace {

// A block's Moller-Trumbore edges (block_detail::MollerTrumboreEdges), made in one 8-lane pass per leaf
// and read by both leaf tests: a triangle's broadcast to a group (test_group), or a row repeated in each
// half of a ray test (test_rays).
struct BlockEdges {
    alignas(32) float e1[3][kWidth];
    alignas(32) float e2[3][kWidth];
    alignas(32) float e1_scale[kWidth];
    alignas(32) float e2_scale[kWidth];
};
[[nodiscard]] BlockEdges block_edges(const Block& block) {
    using Ops = simd::Avx2;
    static_assert(Ops::kWidth == kWidth);
    const auto edges = block_detail::moller_trumbore_edges<Ops>(block_detail::load_vertex<Ops>(block, 0),
                                                                block_detail::load_vertex<Ops>(block, 1),
                                                                block_detail::load_vertex<Ops>(block, 2));
    BlockEdges out;
    Ops::store(out.e1[0], edges.e1.x), Ops::store(out.e1[1], edges.e1.y), Ops::store(out.e1[2], edges.e1.z);
    Ops::store(out.e2[0], edges.e2.x), Ops::store(out.e2[1], edges.e2.y), Ops::store(out.e2[2], edges.e2.z);
    Ops::store(out.e1_scale, edges.e1_scale), Ops::store(out.e2_scale, edges.e2_scale);
    return out;
}

// The lanes of a test that holds rays against whole blocks (PacketLeafTests::test_rays): each 8-lane half
// of the vector is one ray of a group against a block's 8 triangles, as in bvh8's block test, so an AVX-512
// test takes two rays and an AVX2 test one.
template <class Ops>
struct BlockRays;

template <>
struct BlockRays<simd::Avx2> {
    [[maybe_unused]] static constexpr int kRays = 1;  // unused by the AVX-512 compilation (clang warns)
    __m256i index;                                    // the ray's lane in its group

    explicit BlockRays(const std::array<int, 2>& rays) : index(_mm256_set1_epi32(rays[0])) {}
    // Each lane takes its ray's value of a group vector.
    [[nodiscard]] __m256 spread(__m256 group) const { return _mm256_permutevar8x32_ps(group, index); }
    // A block row, 8 floats, in each half.
    [[nodiscard]] static __m256 repeat(const float* row) { return _mm256_load_ps(row); }
    // The first ray's row, `first`, in the first half and the second's in the second.
    [[nodiscard]] static __m256 pair(const float* first, const float*) { return _mm256_load_ps(first); }
};

#if defined(__AVX512F__) && defined(__AVX512DQ__)
template <>
struct BlockRays<simd::Avx512> {
    static constexpr int kRays = 2;
    __m512i index;  // lanes 0-7: the first ray's lane in its group, lanes 8-15: the second's

    explicit BlockRays(const std::array<int, 2>& rays)
        : index(_mm512_mask_set1_epi32(_mm512_set1_epi32(rays[0]), 0xff00, rays[1])) {}
    // The zero-masked forms with every lane set: GCC 12's plain ones read an uninitialised
    // _mm512_undefined_ps() (simd::Avx512::max).
    [[nodiscard]] __m512 spread(__m512 group) const {
        return _mm512_maskz_permutexvar_ps(0xffff, index, group);
    }
    [[nodiscard]] static __m512 repeat(const float* row) {
        return _mm512_maskz_broadcast_f32x8(0xffff, _mm256_load_ps(row));
    }
    [[nodiscard]] static __m512 pair(const float* first, const float* second) {
        return _mm512_insertf32x8(_mm512_castps256_ps512(_mm256_load_ps(first)), _mm256_load_ps(second), 1);
    }
};
#endif

// The most blocks a leaf holds, for the per-leaf arrays of the tests.
constexpr std::uint32_t kMaxLeafBlocks = block_count(BvhAccel::kMaxLeafSize, kWidth);
static_assert(kMaxLeafBlocks * kWidth <= 64, "a leaf's candidates fit one 64-bit mask");

// Where a packet's rays come from. A camera's rays meet most triangles from afar, where many lanes of the
// watertight test are uncertain; rays from a surface (a batch's shadow and bounce rays) meet them near
// their origins, where few are (WatertightLanes::test's kUncertainOften).
enum class RaySource { camera, batch };

// The leaf tests on a loaded packet; the traversal (bvh8_packet_kernel.cpp) calls test_leaf.
template <class Ops, class TriangleTestT>
class PacketLeafTests : public LoadedPacket<Ops, TriangleTestT> {
  protected:
    using Packet = LoadedPacket<Ops, TriangleTestT>;
    using Packet::alive_, Packet::code_lanes_, Packet::codes_, Packet::packet_, Packet::tlimit_max_;
    using Packet::kGroup, Packet::kGroups, Packet::kLanes, Packet::kWatertight;
    using Packet::load_best, Packet::prepare_group, Packet::store_best;
    using typename Packet::Float, typename Packet::GroupBest, typename Packet::Vec3v;

    PacketLeafTests(const Bvh8Accel& bvh, const Geometry& geometry, RaySource source)
        : blocks_(bvh.blocks()),
          geometry_(geometry),
          tolerance_(geometric_tolerance(bvh.bounds())),
          uncertain_often_(kWatertight && source == RaySource::camera) {}

    // The triangles of a leaf (the node's `child` and `prim_count`) against its rays, a group of rays at a
    // time; true when some ray found a (closer) hit. Its triangles' own boxes cull them for each group, so a
    // header's block boxes (has_leaf_boxes) are skipped.
    template <bool kAnyHit, class Answer>
    bool test_leaf(std::uint32_t child, std::uint32_t prim_count, LaneMask rays, std::span<Answer> answers) {
        bool found = false;
        const auto [first_block, end] = leaf_span<kWidth>(child, prim_count);
        // Per block, once: its triangles' boxes, and its spheres, which every group tests without a cull.
        std::array<TriangleBoxes, kMaxLeafBlocks> boxes;
        std::array<unsigned, kMaxLeafBlocks> spheres;
        for (std::uint32_t b = first_block; b < end; ++b) {
            boxes[b - first_block] = triangle_boxes(blocks_[b], tolerance_);
            spheres[b - first_block] = sphere_lanes(blocks_[b]);
        }
        std::array<BlockEdges, kMaxLeafBlocks> edges;  // Moller-Trumbore only, at the first group with a test
        bool edges_ready = false;
        // The groups that hold rays of `rays`, by their bits: a branch on each group's rays was mispredicted
        // (docs/accel/packets.md, "A leaf's groups by their bits"). A group's tests change only its own rays.
        const LaneMask live = rays & alive_;
        unsigned groups = 0;
        for (int group = 0; group < kGroups; ++group)
            groups |= static_cast<unsigned>((live >> (group * kLanes) & kGroup) != 0) << group;
        for (; groups != 0; groups &= groups - 1) {
            const int group = std::countr_zero(groups);
            const auto active = static_cast<unsigned>(live >> (group * kLanes) & kGroup);
            // The group's own interval: its 16 (or 8) rays span a quarter of the packet's frustum.
            const PacketInterval& interval = prepare_group(group);
            std::array<unsigned, kMaxLeafBlocks> candidates;
            alignas(32) float entry[kWidth];
            // The same candidates, kWidth bits a block, for test_group's occlusion loop.
            std::uint64_t candidate_bits = 0;
            for (std::uint32_t b = first_block; b < end; ++b) {
                const TriangleBoxes& block_boxes = boxes[b - first_block];
                candidates[b - first_block] =
                    (cull_boxes(block_boxes.bounds, interval, tlimit_max_, entry) & block_boxes.triangles) |
                    spheres[b - first_block];
                candidate_bits |= std::uint64_t{candidates[b - first_block]} << (kWidth * (b - first_block));
            }
            if (candidate_bits == 0) continue;
            if (!kWatertight && !edges_ready) {
                for (std::uint32_t b = first_block; b < end; ++b)
                    edges[b - first_block] = block_edges(blocks_[b]);
                edges_ready = true;
            }
            if (prefer_ray_tests(first_block, end, candidates, spheres, active))
                found |= test_rays<kAnyHit>(first_block, end, candidates, edges, group, active, answers);
            else if (uncertain_often_)
                found |= test_group<kAnyHit, true>(first_block, end, candidates, candidate_bits, edges, group,
                                                   active, answers);
            else
                found |= test_group<kAnyHit, false>(first_block, end, candidates, candidate_bits, edges,
                                                    group, active, answers);
        }
        return found;
    }

  private:
    // The lanes of a block that hold spheres (in a mixed scene), which the cull cannot bound (NaN vertices).
    [[nodiscard]] unsigned sphere_lanes(const Block& block) const {
        if (geometry_.spheres.empty()) return 0;
        unsigned lanes = 0;
        for (int lane = 0; lane < kWidth; ++lane) {
            if (block.prim[lane] >= geometry_.triangles.size() && block.prim[lane] != Block::kNoPrimitive)
                lanes |= 1u << lane;
        }
        return lanes;
    }

    [[nodiscard]] Vec3v vertex(const Block& block, int v, int lane, const std::array<int, 3>& axes) const {
        return {Ops::broadcast(block.vertex[v][axes[0]][lane]),
                Ops::broadcast(block.vertex[v][axes[1]][lane]),
                Ops::broadcast(block.vertex[v][axes[2]][lane])};
    }

    // Vertex v of a block's 8 triangles for test_rays: the first ray's half in its axis permutation, the
    // second's in its own (BlockRays::pair).
    [[nodiscard]] static Vec3v paired_vertex(const Block& block, int v, const std::array<int, 3>& first_axes,
                                             const std::array<int, 3>& second_axes) {
        using Rays = BlockRays<Ops>;
        return {Rays::pair(block.vertex[v][first_axes[0]], block.vertex[v][second_axes[0]]),
                Rays::pair(block.vertex[v][first_axes[1]], block.vertex[v][second_axes[1]]),
                Rays::pair(block.vertex[v][first_axes[2]], block.vertex[v][second_axes[2]])};
    }

    // Whether the `active` rays of `group` should test the leaf's blocks a ray at a time (test_rays) rather
    // than its candidate triangles a triangle at a time (test_group). Where triangles are small beside the
    // packet's footprint few rays of a group reach a leaf (the dragon: 3.2 of 16, against 3.8 candidates
    // of 8), and most lanes of a broadcast triangle idle. A ray test costs about twice a triangle test with
    // Moller-Trumbore and three times with the watertight test, which loads each ray's vertex rows in its
    // own axis permutation: the weights that measured best (docs/accel/packets.md, "Few rays at a leaf";
    // "Watertight ray tests"). Spheres take the broadcast path.
    [[nodiscard]] bool prefer_ray_tests(std::uint32_t first_block, std::uint32_t end,
                                        const std::array<unsigned, kMaxLeafBlocks>& candidates,
                                        const std::array<unsigned, kMaxLeafBlocks>& spheres,
                                        unsigned active) const {
        constexpr int kRays = BlockRays<Ops>::kRays;
        int triangle_tests = 0, blocks = 0;
        for (std::uint32_t b = first_block; b < end; ++b) {
            if (spheres[b - first_block] != 0) return false;
            triangle_tests += std::popcount(candidates[b - first_block]);
            blocks += candidates[b - first_block] != 0;
        }
        const int ray_tests = (std::popcount(active) + kRays - 1) / kRays * blocks;
        constexpr int kRayTestCost = kWatertight ? 3 : 2;
        return kRayTestCost * ray_tests < triangle_tests;
    }

    // The blocks [first_block, end) against the `active` rays of one group, BlockRays<Ops>::kRays rays per
    // test, each against a block's candidate triangles: the lane kernel of test_group on the same operands,
    // so the same hits. The closest hits are merged in the packet's arrays. The watertight test reads each
    // half's vertices in its own ray's axis permutation.
    template <bool kAnyHit, class Answer>
    bool test_rays(std::uint32_t first_block, std::uint32_t end,
                   const std::array<unsigned, kMaxLeafBlocks>& candidates,
                   const std::array<BlockEdges, kMaxLeafBlocks>& edges, int group, unsigned active,
                   std::span<Answer> answers) {
        using Rays = BlockRays<Ops>;
        const int first = group * kLanes;
        auto spread = [&](const Rays& rays, const float* group_values) {
            return rays.spread(Ops::load(group_values + first));
        };
        auto repeat = [](const float(&soa)[3][kWidth]) {
            return Vec3v{Rays::repeat(soa[0]), Rays::repeat(soa[1]), Rays::repeat(soa[2])};
        };
        bool found = false;
        for (unsigned left = active; left != 0;) {
            // The next rays: a lone last one fills both halves, the second masked off.
            std::array<int, 2> ray;
            ray[0] = std::countr_zero(left), left &= left - 1;
            ray[1] = Rays::kRays == 2 && left != 0 ? std::countr_zero(left) : ray[0];
            if (ray[1] != ray[0]) left &= left - 1;
            const Rays rays(ray);
            const Float tnear = spread(rays, packet_.tnear);
            if constexpr (kWatertight) {
                const std::array<int, 3> first_axes = lane_axes(group, ray[0]),
                                         second_axes = lane_axes(group, ray[1]);
                const block_detail::WatertightLanes<Ops> kernel{
                    spread(rays, packet_.permuted_origin[0]), spread(rays, packet_.permuted_origin[1]),
                    spread(rays, packet_.permuted_origin[2]), spread(rays, packet_.shear[0]),
                    spread(rays, packet_.shear[1]),           spread(rays, packet_.shear[2])};
                found |= test_ray_blocks<kAnyHit>(first_block, end, candidates, first, ray, answers,
                                                  [&](const Block& block, std::uint32_t) {
                                                      return kernel.test(
                                                          paired_vertex(block, 0, first_axes, second_axes),
                                                          paired_vertex(block, 1, first_axes, second_axes),
                                                          paired_vertex(block, 2, first_axes, second_axes),
                                                          tnear, spread(rays, packet_.tlimit));
                                                  });
            } else {
                const block_detail::MollerTrumboreLanes<Ops> kernel(
                    {spread(rays, packet_.origin[0]), spread(rays, packet_.origin[1]),
                     spread(rays, packet_.origin[2])},
                    {spread(rays, packet_.direction[0]), spread(rays, packet_.direction[1]),
                     spread(rays, packet_.direction[2])},
                    spread(rays, packet_.direction_scale));
                found |= test_ray_blocks<kAnyHit>(
                    first_block, end, candidates, first, ray, answers,
                    [&](const Block& block, std::uint32_t b) {
                        const BlockEdges& block_edges = edges[b - first_block];
                        return kernel.test(
                            {repeat(block.vertex[0]), repeat(block_edges.e1), repeat(block_edges.e2),
                             Rays::repeat(block_edges.e1_scale), Rays::repeat(block_edges.e2_scale)},
                            tnear, spread(rays, packet_.tlimit));
                    });
            }
        }
        return found;
    }

    // The axis permutation of lane `lane` of `group` (a code of codes_, Watertight::permutation).
    [[nodiscard]] std::array<int, 3> lane_axes(int group, int lane) const {
        const auto g = static_cast<std::size_t>(group);
        int code = 0;
        for (unsigned codes = codes_[g]; codes != 0; codes &= codes - 1) {
            code = std::countr_zero(codes);
            if ((code_lanes_[g][static_cast<std::size_t>(code)] >> lane) & 1u) break;
        }
        return permutation_axes(code);
    }

    // test_rays' loop over the blocks for the rays `ray` (one, when both are the same) of the group at
    // `first`: test(block, b) is the lane kernel's answer for block b, lane l holding ray[l / 8] against
    // triangle l % 8; a ray an occlusion ended drops out.
    template <bool kAnyHit, class Answer, class Test>
    bool test_ray_blocks(std::uint32_t first_block, std::uint32_t end,
                         const std::array<unsigned, kMaxLeafBlocks>& candidates, int first,
                         const std::array<int, 2>& ray, std::span<Answer> answers, const Test& test) {
        const bool second = ray[1] != ray[0];
        bool found = false;
        for (std::uint32_t b = first_block; b < end; ++b) {
            const unsigned alive = static_cast<unsigned>(alive_ >> first);
            const unsigned block_lanes = candidates[b - first_block];
            const unsigned lanes = ((alive >> ray[0]) & 1u ? block_lanes : 0u) |
                                   (second && ((alive >> ray[1]) & 1u) ? block_lanes << kWidth : 0u);
            if (lanes == 0) continue;
            const Block& block = blocks_[b];
            found |= take_block<kAnyHit>(test(block, b), block, first, ray, lanes, answers);
        }
        return found;
    }

    // test_rays' answer on `lanes`: lane l is ray[l / 8] of the group at `first` against triangle l % 8 of
    // `block`. A closest hit replaces the ray's by closer()'s rule (take's, one lane at a time: hits are
    // few); an occlusion ends the ray; the uncertain lanes go through the scalar test.
    template <bool kAnyHit, class Answer>
    bool take_block(const block_detail::LaneHits<Ops>& result, const Block& block, int first,
                    const std::array<int, 2>& ray, unsigned lanes, std::span<Answer> answers) {
        const unsigned hit_lanes = result.hit_lanes & lanes, scalar_lanes = result.scalar_lanes & lanes;
        if ((hit_lanes | scalar_lanes) == 0) return false;
        alignas(64) float t[kLanes], u[kLanes], v[kLanes];
        Ops::store(t, result.t), Ops::store(u, result.u), Ops::store(v, result.v);
        bool found = false;
        for (unsigned each = hit_lanes; each != 0; each &= each - 1) {
            const int lane = std::countr_zero(each);
            const int i = first + ray[static_cast<std::size_t>(lane / kWidth)];
            const auto prim = static_cast<std::int32_t>(block.prim[lane % kWidth]);
            if constexpr (kAnyHit) {
                answers[static_cast<std::size_t>(i)] = 1;
                alive_ &= ~(LaneMask{1} << i);
                found = true;
            } else if (t[lane] < packet_.tlimit[i] ||
                       (t[lane] == packet_.tlimit[i] && prim < packet_.prim[i])) {
                packet_.tlimit[i] = t[lane], packet_.prim[i] = prim;
                packet_.u[i] = u[lane], packet_.v[i] = v[lane];
                found = true;
            }
        }
        for (unsigned each = scalar_lanes; each != 0; each &= each - 1) {
            const int lane = std::countr_zero(each);
            found |= test_scalar<kAnyHit>(block.prim[lane % kWidth],
                                          first + ray[static_cast<std::size_t>(lane / kWidth)], answers);
        }
        return found;
    }

    [[nodiscard]] static Vec3v broadcast_vec(const float (&soa)[3][kWidth], int lane) {
        return {Ops::broadcast(soa[0][lane]), Ops::broadcast(soa[1][lane]), Ops::broadcast(soa[2][lane])};
    }

    // The blocks [first_block, end) against the `active` rays of one group, each triangle broadcast to the
    // group's lanes: block b's candidates are candidates[b - first_block], which candidate_bits holds again
    // from bit kWidth (b - first_block) on. kUncertainOften: WatertightLanes::test's.
    template <bool kAnyHit, bool kUncertainOften, class Answer>
    bool test_group(std::uint32_t first_block, std::uint32_t end,
                    const std::array<unsigned, kMaxLeafBlocks>& candidates, std::uint64_t candidate_bits,
                    const std::array<BlockEdges, kMaxLeafBlocks>& edges, int group, unsigned active,
                    std::span<Answer> answers) {
        const int first = group * kLanes;
        const Float tnear = Ops::load(&packet_.tnear[first]);
        GroupBest best = load_best(first);
        bool found = false;
        const auto kernel = make_kernel(first);
        // Triangle `lane` of block b against the group's rays.
        auto test_candidate = [&](std::uint32_t b, int lane) {
            const Block& block = blocks_[b];
            const std::uint32_t prim = block.prim[lane];
            if (prim >= geometry_.triangles.size()) {
                found |= take_scalar<kAnyHit>(prim, first, active, best, answers);  // a sphere
            } else if constexpr (kWatertight) {
                for (unsigned codes = codes_[static_cast<std::size_t>(group)]; codes != 0;
                     codes &= codes - 1) {
                    const int code = std::countr_zero(codes);
                    const unsigned lanes =
                        active & code_lanes_[static_cast<std::size_t>(group)][static_cast<std::size_t>(code)];
                    if (lanes == 0) continue;
                    const std::array<int, 3> axes = permutation_axes(code);
                    found |= take<kAnyHit>(kernel.template test<kUncertainOften>(
                                               vertex(block, 0, lane, axes), vertex(block, 1, lane, axes),
                                               vertex(block, 2, lane, axes), tnear, best.t),
                                           prim, first, lanes, active, best, answers);
                }
            } else {
                const BlockEdges& block_edges = edges[b - first_block];
                const block_detail::MollerTrumboreEdges<Ops> triangle{
                    broadcast_vec(block.vertex[0], lane), broadcast_vec(block_edges.e1, lane),
                    broadcast_vec(block_edges.e2, lane), Ops::broadcast(block_edges.e1_scale[lane]),
                    Ops::broadcast(block_edges.e2_scale[lane])};
                found |= take<kAnyHit>(kernel.test(triangle, tnear, best.t), prim, first, active, active,
                                       best, answers);
            }
        };
        if constexpr (kAnyHit) {
            // Occlusion: one loop over the leaf's candidates, where a loop per block ended at a count the
            // predictor cannot learn, once a block; camera packets lost 5-8% with the same loop
            // (docs/accel/packets.md, "Occlusion packets' candidates in one loop").
            for (; candidate_bits != 0; candidate_bits &= candidate_bits - 1) {
                const int bit = std::countr_zero(candidate_bits);
                test_candidate(first_block + static_cast<std::uint32_t>(bit / kWidth), bit % kWidth);
                if (active == 0) return found;
            }
        } else {
            for (std::uint32_t b = first_block; b < end; ++b) {
                for (unsigned each = candidates[b - first_block]; each != 0; each &= each - 1)
                    test_candidate(b, std::countr_zero(each));
            }
            store_best(first, best);
        }
        return found;
    }

    // The lane kernel of the packet's triangle test on the group starting at ray `first`.
    [[nodiscard]] auto make_kernel(int first) const {
        if constexpr (kWatertight) {
            return block_detail::WatertightLanes<Ops>{
                Ops::load(&packet_.permuted_origin[0][first]), Ops::load(&packet_.permuted_origin[1][first]),
                Ops::load(&packet_.permuted_origin[2][first]), Ops::load(&packet_.shear[0][first]),
                Ops::load(&packet_.shear[1][first]),           Ops::load(&packet_.shear[2][first])};
        } else {
            return block_detail::MollerTrumboreLanes<Ops>(load_vec<Ops>(packet_.origin, first),
                                                          load_vec<Ops>(packet_.direction, first),
                                                          Ops::load(&packet_.direction_scale[first]));
        }
    }

    // The kernel's answer for `prim` on `lanes` of the group starting at ray `first`: a closest hit through
    // closer() (the smaller t, then the smaller index, as intersect_block), an occlusion ends the ray; the
    // uncertain lanes go through the scalar test. `active` loses the rays an occlusion ends.
    template <bool kAnyHit, class Answer>
    bool take(const block_detail::LaneHits<Ops>& result, std::uint32_t prim, int first, unsigned lanes,
              unsigned& active, GroupBest& best, std::span<Answer> answers) {
        bool found = false;
        const unsigned hit_lanes = result.hit_lanes & lanes;
        if constexpr (kAnyHit) {
            if (hit_lanes != 0) {
                found = true;
                for (unsigned each = hit_lanes; each != 0; each &= each - 1)
                    answers[static_cast<std::size_t>(first + std::countr_zero(each))] = 1;
                alive_ &= ~(static_cast<LaneMask>(hit_lanes) << first);
                active &= ~hit_lanes;
            }
        } else {
            // Without a branch: whether a lane hits is data the predictor cannot learn.
            found = hit_lanes != 0;
            const Float index = Ops::broadcast_int(static_cast<int>(prim));
            const auto closer = Ops::mask_and(
                Ops::mask_from_bits(hit_lanes),
                Ops::mask_or(Ops::less(result.t, best.t),
                             Ops::mask_and(Ops::equal(result.t, best.t), Ops::less_int(index, best.prim))));
            best = {Ops::select(closer, result.t, best.t), Ops::select(closer, index, best.prim),
                    Ops::select(closer, result.u, best.u), Ops::select(closer, result.v, best.v)};
        }
        const unsigned scalar_lanes = result.scalar_lanes & lanes & active;
        if (scalar_lanes != 0) found |= take_scalar<kAnyHit>(prim, first, scalar_lanes, best, answers);
        if constexpr (kAnyHit)
            active &= static_cast<unsigned>(alive_ >> first) & static_cast<unsigned>(kGroup);
        return found;
    }

    // The scalar test of `prim` on `lanes` of the group starting at ray `first`, through the packet's arrays.
    template <bool kAnyHit, class Answer>
    bool take_scalar(std::uint32_t prim, int first, unsigned lanes, GroupBest& best,
                     std::span<Answer> answers) {
        if constexpr (!kAnyHit) store_best(first, best);
        bool found = false;
        for (unsigned each = lanes; each != 0; each &= each - 1)
            found |= test_scalar<kAnyHit>(prim, first + std::countr_zero(each), answers);
        if constexpr (!kAnyHit) best = load_best(first);
        return found;
    }

    // intersect_primitive or occludes for ray i, from its own Ray.
    template <bool kAnyHit, class Answer>
    bool test_scalar(std::uint32_t prim, int i, std::span<Answer> answers) {
        if (!((alive_ >> i) & 1u)) return false;
        const PreparedRay<TriangleTestT> prepared(
            Ray{{packet_.origin[0][i], packet_.origin[1][i], packet_.origin[2][i]},
                {packet_.direction[0][i], packet_.direction[1][i], packet_.direction[2][i]},
                packet_.tnear[i],
                packet_.tfar[i]});
        if constexpr (kAnyHit) {
            if (!occludes(geometry_, prim, prepared)) return false;
            answers[static_cast<std::size_t>(i)] = 1;
            alive_ &= ~(LaneMask{1} << i);
            return true;
        } else {
            Hit best = packet_.prim[i] == kNoHit
                           ? Hit{}
                           : Hit{packet_.tlimit[i], packet_.prim[i], packet_.u[i], packet_.v[i]};
            if (!intersect_primitive(geometry_, prim, prepared, best)) return false;
            packet_.tlimit[i] = best.t, packet_.prim[i] = best.prim;
            packet_.u[i] = best.u, packet_.v[i] = best.v;
            return true;
        }
    }

  protected:
    const HugePageVector<Block>& blocks_;
    const Geometry& geometry_;

  private:
    float tolerance_;       // the scene's geometric tolerance, by which the triangle boxes are grown
    bool uncertain_often_;  // camera packets, watertight test: test_group's kUncertainOften
};

}  // namespace
}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
