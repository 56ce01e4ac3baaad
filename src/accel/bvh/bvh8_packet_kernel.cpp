// The kernel of bvh8_packet (bvh8_packet.hpp): this one source is compiled once per instruction set, by
// lancer_core for AVX2 (8 rays per instruction) and by lancer_kernels_avx512 for AVX-512 (16), each into its
// own namespace (core/isa_namespace.hpp), and Bvh8PacketAccel picks one when it is built (lancer/isa.hpp).
#include "accel/bvh/bvh8_packet_kernel.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>

#include "accel/build_util.hpp"
#include "accel/bvh/triangle_block.hpp"
#include "accel/packet_batch.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/simd_float.hpp"

#if defined(__AVX2__)
namespace lancer {
inline namespace LANCER_ISA_NAMESPACE {
namespace {

constexpr int kPacketSize = kBvh8PacketSize;
constexpr int kWidth = 8;  // bvh8
using Node = WideBvhNode<kWidth>;
using Block = Bvh8Accel::Block;
using LaneMask = std::uint64_t;  // bit i: ray i of the packet
// A lane's best primitive before any hit: above every index, so that closer()'s tie rule (the smaller index
// wins at equal t) accepts a first hit at exactly tfar, as it does against a missing Hit.
constexpr std::int32_t kNoHit = std::numeric_limits<std::int32_t>::max();

// The watertight test's axis permutations (Watertight::permutation): six codes, 2 kz + (d[kz] < 0).
constexpr int kPermutations = 6;
[[nodiscard]] constexpr std::array<int, 3> permutation_axes(int code) {
    return Watertight::permutation(code / 2, code % 2 != 0);
}

// The packet, one array per coordinate so that a group of rays loads in one instruction. Lanes without a
// valid ray have tlimit = -inf, which no box test passes.
struct alignas(64) PacketRays {
    float origin[3][kPacketSize];
    float direction[3][kPacketSize];
    float inv_direction[3][kPacketSize];
    float tnear[kPacketSize];
    float tfar[kPacketSize];    // the caller's, for the scalar test of a sphere
    float tlimit[kPacketSize];  // the closest hit so far, or tfar
    // Moller-Trumbore's ray data: max |d_i|.
    float direction_scale[kPacketSize];
    // The watertight test's ray data: the origin's kx, ky, kz components and the shear.
    float permuted_origin[3][kPacketSize];
    float shear[3][kPacketSize];
    // The closest hit so far (t is tlimit): kNoHit before the first.
    float u[kPacketSize], v[kPacketSize];
    std::int32_t prim[kPacketSize];
};

// The packet's rays as intervals, for the conservative child test: every ray's origin lies in
// [origin_lo, origin_hi] and its reciprocal direction in [inv_lo, inv_hi], one sign per axis.
struct PacketInterval {
    std::array<float, 3> entry_origin, exit_origin;  // the corner of the origin box each plane distance takes
    std::array<float, 3> inv_lo, inv_hi;
    std::array<int, 3> near_side;  // WideBvhNode::kLo or kHi: the face a ray enters by on each axis
    float tnear_min;

    // The intervals of one axis, its near_side set: the entry is smallest from the origin nearest the far
    // side, the exit largest from the other.
    void set_axis(std::size_t axis, float origin_lo, float origin_hi, float reciprocal_lo,
                  float reciprocal_hi) {
        const bool negative = near_side[axis] == WideBvhNode<8>::kHi;
        entry_origin[axis] = negative ? origin_lo : origin_hi;
        exit_origin[axis] = negative ? origin_hi : origin_lo;
        inv_lo[axis] = reciprocal_lo, inv_hi[axis] = reciprocal_hi;
    }
};

using Boxes = simd::Avx2::Float[2][3];  // [kLo | kHi][axis]: 8 boxes, one per lane

// The boxes (8, one per lane) that some ray of the packet may hit within [tnear_min, tlimit_max]: bit i set,
// with entry[i] a lower bound of where any ray enters box i. Interval arithmetic on the slab test (Overbeck
// et al. 2008): every plane distance fl(fl(b - o) * r) is monotone in o and in r, so the corner
// of the intervals chosen by the signs of b - o and r bounds it over the packet, in the same fp32 operations.
// The exit's widening (widened_slab_exit) is monotone too. A ray whose own test (box_groups) passes thus
// always finds its child's bit set. Empty slots (lo = +inf, hi = -inf) enter at +inf and leave at -inf.
[[nodiscard]] unsigned cull_boxes(const Boxes& bounds, const PacketInterval& packet, float tlimit_max,
                                  float (&entry)[kWidth]) {
    using Ops = simd::Avx2;
    auto t0 = Ops::broadcast(packet.tnear_min), t1 = Ops::broadcast(tlimit_max);
    const auto zero = Ops::broadcast(0.0f);
    const auto grow = Ops::broadcast(kSlabExitGrow), shrink = Ops::broadcast(kSlabExitShrink);
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const int side = packet.near_side[axis];
        const auto inv_lo = Ops::broadcast(packet.inv_lo[axis]), inv_hi = Ops::broadcast(packet.inv_hi[axis]);
        // Smallest entry: the near plane's distance from the farthest origin, times the reciprocal that
        // makes the product smallest (the largest magnitude for a negative distance).
        const auto near_distance = Ops::sub(bounds[side][axis], Ops::broadcast(packet.entry_origin[axis]));
        const auto near_plane =
            Ops::mul(near_distance, Ops::select_if_greater(zero, near_distance, inv_hi, inv_lo));
        // Largest exit, widened.
        const auto far_distance = Ops::sub(bounds[1 - side][axis], Ops::broadcast(packet.exit_origin[axis]));
        const auto far_unwidened =
            Ops::mul(far_distance, Ops::select_if_greater(zero, far_distance, inv_lo, inv_hi));
        const auto far_plane =
            Ops::mul(far_unwidened, Ops::select_if_greater(far_unwidened, zero, grow, shrink));
        t0 = Ops::max(near_plane, t0);
        t1 = Ops::min(far_plane, t1);
    }
    Ops::store(entry, t0);
    return Ops::bits(Ops::less_equal(t0, t1));
}

// cull_boxes on the 8 children of a node.
[[nodiscard]] unsigned cull_children(const Node& node, const PacketInterval& packet, float tlimit_max,
                                     float (&entry)[kWidth]) {
    using Ops = simd::Avx2;
    Boxes bounds;
    for (int side = 0; side < 2; ++side) {
        for (int axis = 0; axis < 3; ++axis)
            bounds[side][axis] = Ops::load(node.bounds[side][axis]);
    }
    return cull_boxes(bounds, packet, tlimit_max, entry);
}

// The bounding boxes of a block's 8 triangles grown by the scene's geometric tolerance, for cull_boxes: the
// triangle tests report hits up to a rounding error outside their triangle, and the grown box still holds
// them (the argument for a leaf's box, which the build grows by the same tolerance;
// docs/numerical-contract.md, "Boxes"). `triangles`: the lanes that hold one (padding and spheres have NaN
// vertices, whose boxes cull_boxes would pass: its max and min drop NaN operands).
struct TriangleBoxes {
    Boxes bounds;
    unsigned triangles;
};
[[nodiscard]] TriangleBoxes triangle_boxes(const Block& block, float tolerance) {
    using Ops = simd::Avx2;
    const auto margin = Ops::broadcast(tolerance);
    TriangleBoxes boxes;
    for (int axis = 0; axis < 3; ++axis) {
        const auto v0 = Ops::load(block.vertex[0][axis]), v1 = Ops::load(block.vertex[1][axis]),
                   v2 = Ops::load(block.vertex[2][axis]);
        boxes.bounds[Node::kLo][axis] = Ops::sub(Ops::min(v0, Ops::min(v1, v2)), margin);
        boxes.bounds[Node::kHi][axis] = Ops::add(Ops::max(v0, Ops::max(v1, v2)), margin);
    }
    boxes.triangles = Ops::bits(Ops::equal(boxes.bounds[Node::kLo][0], boxes.bounds[Node::kLo][0]));
    return boxes;
}

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

// The lanes of a test that holds rays against whole blocks (Bvh8PacketTraversal::test_rays): each 8-lane half
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
};
#endif

// intersect_box on the packet's rays `rays` against child `slot` of `node`, a group of Ops::kWidth rays per
// instruction: the rays whose [tnear, tlimit] meets the child's box. Every ray's reciprocal direction is
// finite and of the packet's sign on each axis, so no plane distance is NaN and the near face is the same
// for all: the operations are those of bvh8's intersect_children, lane for lane.
template <class Ops>
[[nodiscard]] LaneMask box_groups(const PacketRays& packet, const PacketInterval& interval, const Node& node,
                                  int slot, LaneMask rays) {
    constexpr int lanes = Ops::kWidth;
    constexpr LaneMask kGroup = (LaneMask{1} << lanes) - 1;
    typename Ops::Float near_bound[3], far_bound[3];
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const int side = interval.near_side[axis];
        near_bound[axis] = Ops::broadcast(node.bounds[side][axis][slot]);
        far_bound[axis] = Ops::broadcast(node.bounds[1 - side][axis][slot]);
    }
    LaneMask result = 0;
    for (int first = 0; first < kPacketSize; first += lanes) {
        const LaneMask group = (rays >> first) & kGroup;
        if (group == 0) continue;
        auto t0 = Ops::load(&packet.tnear[first]);
        auto t1 = Ops::load(&packet.tlimit[first]);
        for (std::size_t axis = 0; axis < 3; ++axis) {
            clip_slab<Ops>(near_bound[axis], far_bound[axis], Ops::load(&packet.origin[axis][first]),
                           Ops::load(&packet.inv_direction[axis][first]), t0, t1);
        }
        result |= (static_cast<LaneMask>(Ops::bits(Ops::less_equal(t0, t1))) & group) << first;
    }
    return result;
}

template <class Ops>
[[nodiscard]] block_detail::Vec3v<Ops> load_vec(const float (&soa)[3][kPacketSize], int first) {
    return {Ops::load(&soa[0][first]), Ops::load(&soa[1][first]), Ops::load(&soa[2][first])};
}

// A child the traversal will visit: `slot` of `parent`, with the rays that met the parent and a lower bound
// of where any of them enters the child.
struct StackEntry {
    const Node* parent;
    int slot;
    float entry;
    LaneMask rays;
};
constexpr int kStackSize = kWidth * BvhAccel::kMaxDepth + 1;
constexpr std::uint32_t kMaxLeafBlocks = block_count(BvhAccel::kMaxLeafSize, kWidth);

// One packet: loaded, then traced. Ops: the lane width of the box and triangle tests.
template <class Ops, class TriangleTestT>
class Bvh8PacketTraversal {
    static constexpr int kLanes = Ops::kWidth;
    static constexpr LaneMask kGroup = (LaneMask{1} << kLanes) - 1;
    static_assert(kPacketSize % kLanes == 0);
    static constexpr int kGroups = kPacketSize / kLanes;
    static constexpr bool kWatertight = std::is_same_v<TriangleTestT, Watertight>;
    using Float = typename Ops::Float;
    using Vec3v = block_detail::Vec3v<Ops>;

  public:
    Bvh8PacketTraversal(const Bvh8Accel& bvh, const Geometry& geometry)
        : nodes_(bvh.nodes()),
          blocks_(bvh.blocks()),
          geometry_(geometry),
          tolerance_(geometric_tolerance(bvh.bounds())) {}

    // Loads rays.size() <= kPacketSize rays; false when the packet cannot be traced together: two valid rays
    // disagree on a direction sign, or a reciprocal direction is not finite (a zero or denormal component,
    // whose NaN plane distances the interval cull does not bound).
    [[nodiscard]] bool load(std::span<const Ray> rays) {
        const Ray* source = rays.data();
        if (rays.size() < static_cast<std::size_t>(kPacketSize)) {
            // A partial packet, padded with rays of zero direction (invalid: no lane of theirs is traced).
            std::copy(rays.begin(), rays.end(), padded_rays_.begin());
            std::fill(padded_rays_.begin() + static_cast<std::ptrdiff_t>(rays.size()), padded_rays_.end(),
                      Ray{{}, {}, 0.0f, 0.0f});
            source = padded_rays_.data();
        }
        // The fields of kLanes consecutive rays, transposed: ox oy oz dx dy dz tnear tfar.
        static_assert(sizeof(Ray) == 8 * sizeof(float) && offsetof(Ray, tfar) == 7 * sizeof(float));
        return load_groups(
            [&](int first, Float(&fields)[8]) { Ops::load_fields8(&source[first].origin.x, fields); });
    }

    // The same from a packet in the caller's SoA layout: its arrays are the fields, read in place.
    [[nodiscard]] bool load(const RayPacket& rays) {
        const RayPacket* source = &rays;
        if (rays.size < kPacketSize) {
            padded_packet_ = rays;
            for (int lane = rays.size; lane < kPacketSize; ++lane)
                padded_packet_.set(lane, Ray{{}, {}, 0.0f, 0.0f});
            source = &padded_packet_;
        }
        return load_groups([&](int first, Float(&fields)[8]) {
            for (int axis = 0; axis < 3; ++axis) {
                fields[axis] = Ops::load(&source->origin[axis][first]);
                fields[axis + 3] = Ops::load(&source->direction[axis][first]);
            }
            fields[6] = Ops::load(&source->tnear[first]);
            fields[7] = Ops::load(&source->tfar[first]);
        });
    }

  private:
    // A group of rays at a time, fields(first, fields) giving the eight fields of the group's lanes: is_valid
    // and SlabRay lane by lane, in the same fp32 operations (the triangle test's RayData waits for a leaf:
    // prepare_group).
    template <class Fields>
    [[nodiscard]] bool load_groups(Fields&& fields_of) {
        const Float infinity = Ops::broadcast(kInfinity), minus_infinity = Ops::broadcast(-kInfinity);
        const Float zero = Ops::broadcast(0.0f), one = Ops::broadcast(1.0f);
        Float origin_lo[3], origin_hi[3], inv_lo[3], inv_hi[3];
        for (int axis = 0; axis < 3; ++axis) {
            origin_lo[axis] = inv_lo[axis] = infinity;
            origin_hi[axis] = inv_hi[axis] = minus_infinity;
        }
        Float tnear_min = infinity;
        std::array<LaneMask, 3> negative{};
        valid_ = 0;
        groups_ready_ = 0;
        code_lanes_ = {};
        for (int group = 0; group < kGroups; ++group) {
            const int first = group * kLanes;
            Float fields[8];
            fields_of(first, fields);
            const Float origin[3] = {fields[0], fields[1], fields[2]};
            const Float direction[3] = {fields[3], fields[4], fields[5]};
            const Float tnear = fields[6], tfar = fields[7];
            // is_valid: NaN compares false, so `|x| < inf` is isfinite and `tfar == tfar` is !isnan.
            auto valid = Ops::mask_and(Ops::less(Ops::abs(tnear), infinity),
                                       Ops::mask_and(Ops::equal(tfar, tfar), Ops::less_equal(tnear, tfar)));
            auto nonzero = Ops::greater(Ops::abs(direction[0]), zero);
            for (int axis = 0; axis < 3; ++axis) {
                valid = Ops::mask_and(valid, Ops::mask_and(Ops::less(Ops::abs(origin[axis]), infinity),
                                                           Ops::less(Ops::abs(direction[axis]), infinity)));
                if (axis > 0) nonzero = Ops::mask_or(nonzero, Ops::greater(Ops::abs(direction[axis]), zero));
            }
            valid = Ops::mask_and(valid, nonzero);
            const unsigned valid_lanes = Ops::bits(valid);
            valid_ |= static_cast<LaneMask>(valid_lanes) << first;
            for (int axis = 0; axis < 3; ++axis) {
                const Float inv_direction = Ops::div(one, direction[axis]);  // SlabRay
                if ((Ops::bits(Ops::less(Ops::abs(inv_direction), infinity)) & valid_lanes) != valid_lanes)
                    return false;
                negative[axis] |= static_cast<LaneMask>(Ops::sign_bits(direction[axis]) & valid_lanes)
                                  << first;
                origin_lo[axis] = Ops::min(Ops::select(valid, origin[axis], infinity), origin_lo[axis]);
                origin_hi[axis] = Ops::max(Ops::select(valid, origin[axis], minus_infinity), origin_hi[axis]);
                inv_lo[axis] = Ops::min(Ops::select(valid, inv_direction, infinity), inv_lo[axis]);
                inv_hi[axis] = Ops::max(Ops::select(valid, inv_direction, minus_infinity), inv_hi[axis]);
                Ops::store(&packet_.origin[axis][first], origin[axis]);
                Ops::store(&packet_.direction[axis][first], direction[axis]);
                Ops::store(&packet_.inv_direction[axis][first], inv_direction);
            }
            const Float lane_tnear = Ops::select(valid, tnear, infinity);
            tnear_min = Ops::min(lane_tnear, tnear_min);
            Ops::store(&packet_.tnear[first], lane_tnear);
            Ops::store(&packet_.tfar[first], tfar);
            Ops::store(&packet_.tlimit[first], Ops::select(valid, tfar, minus_infinity));
        }
        for (std::size_t axis = 0; axis < 3; ++axis) {
            if (negative[axis] != 0 && negative[axis] != valid_) return false;
            interval_.near_side[axis] = negative[axis] != 0 ? Node::kHi : Node::kLo;
            interval_.set_axis(axis, Ops::reduce_min(origin_lo[axis]), Ops::reduce_max(origin_hi[axis]),
                               Ops::reduce_min(inv_lo[axis]), Ops::reduce_max(inv_hi[axis]));
        }
        interval_.tnear_min = Ops::reduce_min(tnear_min);
        std::fill(std::begin(packet_.prim), std::end(packet_.prim), kNoHit);
        return true;
    }

  public:
    // Front to back: the children that survive the cull are ordered by their entry bound and pushed, the
    // nearest on top; a popped child is tested against its rays, and skipped when it is entered beyond
    // every ray's closest hit. kAnyHit: a ray leaves the packet at its first hit. `answers` starts as
    // misses; on return answers[i] is ray i's closest hit (Hit) or occlusion (uint8).
    template <bool kAnyHit, bool kCount, class Answer>
    void trace(std::span<Answer> answers, TraversalCounters& counts) {
        alive_ = valid_;
        if (nodes_.empty() || alive_ == 0) return;
        tlimit_max_ = max_tlimit();
        std::array<StackEntry, kStackSize> stack;
        int stack_size = 0;
        const Node* node = &nodes_[0];
        LaneMask rays = alive_;
        while (true) {
            // INNER: cull the children, push the survivors farthest first.
            if constexpr (kCount) counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(rays));
            alignas(32) float entry[kWidth];
            std::array<int, kWidth> order;
            const int count =
                order_by_entry<kWidth>(cull_children(*node, interval_, tlimit_max_, entry), entry, order);
            for (int k = count - 1; k >= 0; --k)
                stack[stack_size++] = {node, order[k], entry[order[k]], rays};
            // POP until an inner child with rays in it, testing the leaves on the way.
            while (true) {
                if (stack_size == 0) return;
                const StackEntry popped = stack[--stack_size];
                if (popped.entry > tlimit_max_) continue;
                rays = box_groups<Ops>(packet_, interval_, *popped.parent, popped.slot, popped.rays & alive_);
                if (rays == 0) continue;
                const std::uint32_t prim_count = popped.parent->prim_count[popped.slot];
                const std::uint32_t child = popped.parent->child[popped.slot];
                if (prim_count == 0) {
                    node = &nodes_[child];
                    break;
                }
                if constexpr (kCount) {
                    counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(rays));
                    counts.prims_tested += static_cast<std::uint64_t>(prim_count) *
                                           static_cast<std::uint64_t>(std::popcount(rays));
                }
                if (test_leaf<kAnyHit>(child, prim_count, rays, answers)) {
                    if constexpr (kAnyHit) {
                        if (alive_ == 0) return;
                    } else {
                        tlimit_max_ = max_tlimit();
                    }
                }
            }
        }
    }

    // The closest hits of the loaded rays, into the first rays.size() of `hits`, a group at a time. Invalid
    // rays never hit, so their prim is still kNoHit.
    void store_hits(std::span<Hit> hits) const {
        static_assert(sizeof(Hit) == 4 * sizeof(float) && offsetof(Hit, prim) == 4 && offsetof(Hit, v) == 12);
        for (std::size_t first = 0; first < hits.size(); first += kLanes) {
            const GroupBest answer = group_answer(static_cast<int>(first));
            alignas(64) Hit group[kLanes];
            Ops::store_interleaved(reinterpret_cast<float*>(group), answer.t, answer.prim, answer.u,
                                   answer.v);
            std::copy_n(group, std::min<std::size_t>(kLanes, hits.size() - first),
                        hits.begin() + static_cast<std::ptrdiff_t>(first));
        }
    }

    // The same into a hit packet's arrays, every lane (those past the caller's rays are unspecified).
    void store_hits(HitPacket& hits) const {
        for (int first = 0; first < kPacketSize; first += kLanes) {
            const GroupBest answer = group_answer(first);
            Ops::store(&hits.t[first], answer.t);
            Ops::store(reinterpret_cast<float*>(&hits.prim[first]), answer.prim);
            Ops::store(&hits.u[first], answer.u);
            Ops::store(&hits.v[first], answer.v);
        }
    }

  private:
    // Watertight::RayData lane by lane: kz the dominant axis (max_axis: the first of equal magnitudes), kx
    // and ky the next two, swapped where the direction along kz is negative; the lanes of each of the six
    // permutations are recorded for the leaf test.
    void load_watertight(int group, const Float (&origin)[3], const Float (&direction)[3],
                         unsigned valid_lanes) {
        const int first = group * kLanes;
        const Float ax = Ops::abs(direction[0]), ay = Ops::abs(direction[1]), az = Ops::abs(direction[2]);
        // a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2); a valid lane has no NaN, so !(a.x >= a.y)
        // is a.y > a.x.
        const auto is_x = Ops::mask_and(Ops::greater_equal(ax, ay), Ops::greater_equal(ax, az));
        const auto is_y = Ops::mask_and(Ops::greater(ay, ax), Ops::greater_equal(ay, az));
        const unsigned kz_x = Ops::bits(is_x), kz_y = Ops::bits(is_y);
        // Component k of Watertight::permutation(kz, negative), lane by lane by the kz masks.
        auto along = [&](const Float(&v)[3], int k, bool negative) {
            const auto axis = [&](int kz) {
                return Watertight::permutation(kz, negative)[static_cast<std::size_t>(k)];
            };
            return Ops::select(is_x, v[axis(0)], Ops::select(is_y, v[axis(1)], v[axis(2)]));
        };
        const Float d_kz = along(direction, 2, false);
        const auto swapped = Ops::less(d_kz, Ops::broadcast(0.0f));
        auto permuted = [&](const Float(&v)[3], int k) {
            return Ops::select(swapped, along(v, k, true), along(v, k, false));
        };
        const Float d_kx = permuted(direction, 0), d_ky = permuted(direction, 1);
        for (int k = 0; k < 3; ++k)
            Ops::store(&packet_.permuted_origin[k][first], permuted(origin, k));
        Ops::store(&packet_.shear[0][first], Ops::div(d_kx, d_kz));
        Ops::store(&packet_.shear[1][first], Ops::div(d_ky, d_kz));
        Ops::store(&packet_.shear[2][first], Ops::div(Ops::broadcast(1.0f), d_kz));
        const unsigned swapped_lanes = Ops::bits(swapped);
        const unsigned kz_lanes[3] = {kz_x, kz_y, ~(kz_x | kz_y)};
        for (int kz = 0; kz < 3; ++kz) {
            auto& lanes = code_lanes_[static_cast<std::size_t>(group)];
            lanes[static_cast<std::size_t>(2 * kz)] = kz_lanes[kz] & ~swapped_lanes & valid_lanes;
            lanes[static_cast<std::size_t>(2 * kz + 1)] = kz_lanes[kz] & swapped_lanes & valid_lanes;
        }
    }

    [[nodiscard]] float max_tlimit() const {
        auto most = Ops::load(&packet_.tlimit[0]);
        for (int first = kLanes; first < kPacketSize; first += kLanes)
            most = Ops::max(Ops::load(&packet_.tlimit[first]), most);
        alignas(64) float lanes[kLanes];
        Ops::store(lanes, most);
        return *std::max_element(lanes, lanes + kLanes);
    }

    // The closest hit of a group's rays so far, held in registers while a leaf is tested; prim carries the
    // int32 index bit for bit.
    struct GroupBest {
        Float t, prim, u, v;
    };
    [[nodiscard]] GroupBest load_best(int first) const {
        return {Ops::load(&packet_.tlimit[first]),
                Ops::load(reinterpret_cast<const float*>(&packet_.prim[first])), Ops::load(&packet_.u[first]),
                Ops::load(&packet_.v[first])};
    }
    void store_best(int first, const GroupBest& best) {
        Ops::store(&packet_.tlimit[first], best.t);
        Ops::store(reinterpret_cast<float*>(&packet_.prim[first]), best.prim);
        Ops::store(&packet_.u[first], best.u), Ops::store(&packet_.v[first], best.v);
    }
    // The group's closest hits as `Hit` fields: a lane still at kNoHit (no hit, or an invalid ray) answers a
    // miss, Hit{}'s t = inf, prim -1, u = v = 0.
    [[nodiscard]] GroupBest group_answer(int first) const {
        const GroupBest best = load_best(first);
        const auto missed = Ops::equal_int(best.prim, Ops::broadcast_int(kNoHit));
        const Float zero = Ops::broadcast(0.0f);
        return {Ops::select(missed, Ops::broadcast(kInfinity), best.t),
                Ops::select(missed, Ops::broadcast_int(-1), best.prim), Ops::select(missed, zero, best.u),
                Ops::select(missed, zero, best.v)};
    }

    // At group `group`'s first leaf: the interval of its valid rays and their triangle test's RayData. Most
    // packets reach no leaf, so neither is made at loading.
    [[nodiscard]] const PacketInterval& prepare_group(int group) {
        PacketInterval& interval = group_intervals_[static_cast<std::size_t>(group)];
        if ((groups_ready_ >> group) & 1u) return interval;
        groups_ready_ |= 1u << group;
        const int first = group * kLanes;
        const unsigned valid_lanes = static_cast<unsigned>(valid_ >> first) & static_cast<unsigned>(kGroup);
        const auto valid = Ops::mask_from_bits(valid_lanes);
        const Float infinity = Ops::broadcast(kInfinity), minus_infinity = Ops::broadcast(-kInfinity);
        const Vec3v origins = load_vec<Ops>(packet_.origin, first);
        const Vec3v directions = load_vec<Ops>(packet_.direction, first);
        if constexpr (kWatertight) {
            load_watertight(group, {origins.x, origins.y, origins.z},
                            {directions.x, directions.y, directions.z}, valid_lanes);
        } else {
            const Float scale =
                Ops::max(Ops::abs(directions.x), Ops::max(Ops::abs(directions.y), Ops::abs(directions.z)));
            Ops::store(&packet_.direction_scale[first], scale);  // MollerTrumbore::RayData
        }
        interval.near_side = interval_.near_side;
        for (std::size_t axis = 0; axis < 3; ++axis) {
            const Float origin = Ops::load(&packet_.origin[axis][first]);
            const Float inv_direction = Ops::load(&packet_.inv_direction[axis][first]);
            interval.set_axis(axis, Ops::reduce_min(Ops::select(valid, origin, infinity)),
                              Ops::reduce_max(Ops::select(valid, origin, minus_infinity)),
                              Ops::reduce_min(Ops::select(valid, inv_direction, infinity)),
                              Ops::reduce_max(Ops::select(valid, inv_direction, minus_infinity)));
        }
        interval.tnear_min = Ops::reduce_min(Ops::load(&packet_.tnear[first]));  // +inf in invalid lanes
        return interval;
    }

    // The triangles of a leaf against its rays, a group of rays at a time; true when some ray found a
    // (closer) hit.
    template <bool kAnyHit, class Answer>
    bool test_leaf(std::uint32_t first_block, std::uint32_t prim_count, LaneMask rays,
                   std::span<Answer> answers) {
        bool found = false;
        const std::uint32_t end = first_block + block_count(prim_count, kWidth);
        // Per block, once: its triangles' boxes, and its spheres, which every group tests without a cull.
        std::array<TriangleBoxes, kMaxLeafBlocks> boxes;
        std::array<unsigned, kMaxLeafBlocks> spheres;
        for (std::uint32_t b = first_block; b < end; ++b) {
            boxes[b - first_block] = triangle_boxes(blocks_[b], tolerance_);
            spheres[b - first_block] = sphere_lanes(blocks_[b]);
        }
        std::array<BlockEdges, kMaxLeafBlocks> edges;  // Moller-Trumbore only, at the first group with a test
        bool edges_ready = false;
        for (int group = 0; group < kGroups; ++group) {
            const auto active = static_cast<unsigned>((rays & alive_) >> (group * kLanes) & kGroup);
            if (active == 0) continue;
            // The group's own interval: its 16 (or 8) rays span a quarter of the packet's frustum.
            const PacketInterval& interval = prepare_group(group);
            std::array<unsigned, kMaxLeafBlocks> candidates;
            alignas(32) float entry[kWidth];
            unsigned any = 0;
            for (std::uint32_t b = first_block; b < end; ++b) {
                const TriangleBoxes& block_boxes = boxes[b - first_block];
                any |= candidates[b - first_block] =
                    (cull_boxes(block_boxes.bounds, interval, tlimit_max_, entry) & block_boxes.triangles) |
                    spheres[b - first_block];
            }
            if (any == 0) continue;
            if (!kWatertight && !edges_ready) {
                for (std::uint32_t b = first_block; b < end; ++b)
                    edges[b - first_block] = block_edges(blocks_[b]);
                edges_ready = true;
            }
            if (prefer_ray_tests(first_block, end, candidates, spheres, active))
                found |= test_rays<kAnyHit>(first_block, end, candidates, edges, group, active, answers);
            else
                found |= test_group<kAnyHit>(first_block, end, candidates, edges, group, active, answers);
        }
        return found;
    }

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

    // Whether the `active` rays of `group` should test the leaf's blocks a ray at a time (test_rays) rather
    // than its candidate triangles a triangle at a time (test_group). Where triangles are small beside the
    // packet's footprint few rays of a group reach a leaf (the dragon: 3.2 of 16, against 3.8 candidates
    // of 8), and most lanes of a broadcast triangle idle. A ray test costs about twice a triangle test
    // (docs/accel/packets.md, "Few rays at a leaf"). Moller-Trumbore only: the watertight kernel stops
    // before its division when no lane survives its edge signs, so idle lanes cost it less, and it lost
    // ground on the bunny and the armadillo with ray tests. Spheres take the broadcast path.
    [[nodiscard]] bool prefer_ray_tests(std::uint32_t first_block, std::uint32_t end,
                                        const std::array<unsigned, kMaxLeafBlocks>& candidates,
                                        const std::array<unsigned, kMaxLeafBlocks>& spheres,
                                        unsigned active) const {
        if constexpr (kWatertight) return false;
        constexpr int kRays = BlockRays<Ops>::kRays;
        int triangle_tests = 0, blocks = 0;
        for (std::uint32_t b = first_block; b < end; ++b) {
            if (spheres[b - first_block] != 0) return false;
            triangle_tests += std::popcount(candidates[b - first_block]);
            blocks += candidates[b - first_block] != 0;
        }
        const int ray_tests = (std::popcount(active) + kRays - 1) / kRays * blocks;
        return 2 * ray_tests < triangle_tests;
    }

    // Moller-Trumbore on the blocks [first_block, end) against the `active` rays of one group,
    // BlockRays<Ops>::kRays rays per test, each against a block's candidate triangles: the lane kernel of
    // test_group on the same operands, so the same hits. The closest hits are merged in the packet's arrays.
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
            const bool second = ray[1] != ray[0];
            if (second) left &= left - 1;
            const Rays rays(ray);
            const block_detail::MollerTrumboreLanes<Ops> kernel(
                {spread(rays, packet_.origin[0]), spread(rays, packet_.origin[1]),
                 spread(rays, packet_.origin[2])},
                {spread(rays, packet_.direction[0]), spread(rays, packet_.direction[1]),
                 spread(rays, packet_.direction[2])},
                spread(rays, packet_.direction_scale));
            const Float tnear = spread(rays, packet_.tnear);
            for (std::uint32_t b = first_block; b < end; ++b) {
                // A ray an occlusion ended drops out.
                const unsigned alive = static_cast<unsigned>(alive_ >> first);
                const unsigned block_lanes = candidates[b - first_block];
                const unsigned lanes = ((alive >> ray[0]) & 1u ? block_lanes : 0u) |
                                       (second && ((alive >> ray[1]) & 1u) ? block_lanes << kWidth : 0u);
                if (lanes == 0) continue;
                const Block& block = blocks_[b];
                const BlockEdges& block_edges = edges[b - first_block];
                const auto result =
                    kernel.test({repeat(block.vertex[0]), repeat(block_edges.e1), repeat(block_edges.e2),
                                 Rays::repeat(block_edges.e1_scale), Rays::repeat(block_edges.e2_scale)},
                                tnear, spread(rays, packet_.tlimit));
                found |= take_block<kAnyHit>(result, block, first, ray, lanes, answers);
            }
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
    // group's lanes.
    template <bool kAnyHit, class Answer>
    bool test_group(std::uint32_t first_block, std::uint32_t end,
                    const std::array<unsigned, kMaxLeafBlocks>& candidates,
                    const std::array<BlockEdges, kMaxLeafBlocks>& edges, int group, unsigned active,
                    std::span<Answer> answers) {
        const int first = group * kLanes;
        const Float tnear = Ops::load(&packet_.tnear[first]);
        GroupBest best = load_best(first);
        bool found = false;
        const auto kernel = make_kernel(first);
        for (std::uint32_t b = first_block; b < end; ++b) {
            const Block& block = blocks_[b];
            for (unsigned each = candidates[b - first_block]; each != 0; each &= each - 1) {
                const int lane = std::countr_zero(each);
                const std::uint32_t prim = block.prim[lane];
                if (prim >= geometry_.triangles.size()) {
                    found |= take_scalar<kAnyHit>(prim, first, active, best, answers);  // a sphere
                } else if constexpr (kWatertight) {
                    for (int code = 0; code < kPermutations; ++code) {
                        const unsigned lanes =
                            active &
                            code_lanes_[static_cast<std::size_t>(group)][static_cast<std::size_t>(code)];
                        if (lanes == 0) continue;
                        const std::array<int, 3> axes = permutation_axes(code);
                        found |= take<kAnyHit>(
                            kernel.test(vertex(block, 0, lane, axes), vertex(block, 1, lane, axes),
                                        vertex(block, 2, lane, axes), tnear, best.t, lanes),
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
                if constexpr (kAnyHit) {
                    if (active == 0) return found;
                }
            }
        }
        if constexpr (!kAnyHit) store_best(first, best);
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

    const std::vector<Node>& nodes_;
    const std::vector<Block>& blocks_;
    const Geometry& geometry_;
    float tolerance_;  // the scene's geometric tolerance, by which the triangle boxes are grown
    std::array<Ray, kPacketSize> padded_rays_;
    RayPacket padded_packet_;
    PacketRays packet_;
    PacketInterval interval_;
    std::array<PacketInterval, kGroups> group_intervals_;
    unsigned groups_ready_ = 0;  // bit g: prepare_group(g) has run
    // Per group of lanes, the lanes of each watertight axis permutation.
    std::array<std::array<unsigned, kPermutations>, kGroups> code_lanes_{};
    LaneMask valid_ = 0, alive_ = 0;
    float tlimit_max_ = 0.0f;  // the largest tlimit of the packet
};

// Cuts the batch into packets of consecutive rays, traces those that can go together and hands the others
// to bvh8. Answer: Hit (closest hit) or std::uint8_t (occlusion, kAnyHit).
template <class Ops, bool kAnyHit, class Answer>
void trace_batch(const Bvh8Accel& bvh, const Geometry& geometry, TriangleTest test, std::span<const Ray> rays,
                 std::span<Answer> answers, TraversalCounters* counters) {
    dispatch_policies(test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        Bvh8PacketTraversal<Ops, TriangleTestT> tracer(bvh, geometry);
        for_each_packet<static_cast<std::size_t>(kPacketSize), kAnyHit, kCount>(
            rays, answers, bvh, counts,
            [&](std::span<const Ray> packet_rays, std::span<Answer> packet_answers) {
                if (!tracer.load(packet_rays)) return false;
                if constexpr (kAnyHit) {
                    std::fill(packet_answers.begin(), packet_answers.end(), Answer{});
                    tracer.template trace<true, kCount>(packet_answers, counts);
                } else {
                    tracer.template trace<false, kCount>(packet_answers, counts);
                    tracer.store_hits(packet_answers);
                }
                return true;
            });
        if constexpr (kCount) *counters += counts;
    });
}

// One packet in the caller's SoA layout, traced in place, or through bvh8 a ray at a time when its rays
// cannot go together.
template <class Ops>
void trace_soa_packet(const Bvh8Accel& bvh, const Geometry& geometry, TriangleTest test,
                      const RayPacket& rays, HitPacket& hits, TraversalCounters* counters) {
    dispatch_policies(test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        Bvh8PacketTraversal<Ops, TriangleTestT> tracer(bvh, geometry);
        if (tracer.load(rays)) {
            tracer.template trace<false, kCount>(std::span<Hit>(), counts);
            tracer.store_hits(hits);
            if constexpr (kCount) {
                counts.rays += static_cast<std::uint64_t>(rays.size);
                *counters += counts;
            }
            return;
        }
        trace_packet_as_batch(rays, hits, [&](std::span<const Ray> batch, std::span<Hit> batch_hits) {
            bvh.intersect(batch, batch_hits, counters);
        });
    });
}

#if defined(LANCER_KERNEL_AVX512)
using KernelOps = simd::Avx512;
#else
using KernelOps = simd::Avx2;
#endif

void intersect(const Bvh8Accel& bvh, const Geometry& geometry, TriangleTest test, std::span<const Ray> rays,
               std::span<Hit> hits, TraversalCounters* counters) {
    trace_batch<KernelOps, false>(bvh, geometry, test, rays, hits, counters);
}

void occluded(const Bvh8Accel& bvh, const Geometry& geometry, TriangleTest test, std::span<const Ray> rays,
              std::span<std::uint8_t> occluded, TraversalCounters* counters) {
    trace_batch<KernelOps, true>(bvh, geometry, test, rays, occluded, counters);
}

void intersect_packet(const Bvh8Accel& bvh, const Geometry& geometry, TriangleTest test,
                      const RayPacket& rays, HitPacket& hits, TraversalCounters* counters) {
    trace_soa_packet<KernelOps>(bvh, geometry, test, rays, hits, counters);
}

}  // namespace

const Bvh8PacketKernels& bvh8_packet_kernels() {
    static constexpr Bvh8PacketKernels kernels = {KernelOps::kWidth, intersect, occluded, intersect_packet};
    return kernels;
}

}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
