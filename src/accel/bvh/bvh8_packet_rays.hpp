// The packet that bvh8_packet's kernel (bvh8_packet_kernel.cpp) traces: its rays loaded into one array per
// coordinate and checked to go together, their bounds as intervals for the node test
// (bvh8_packet_node_test.hpp), each group's triangle-test ray data, made at its first leaf, and the closest
// hits so far. Like the node test and the leaf tests (bvh8_packet_leaf_tests.hpp), it is included by the
// kernel's source alone, which is compiled once per instruction set: its code is in an anonymous namespace
// inside the instruction set's (core/isa_namespace.hpp, docs/isa.md).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <span>
#include <type_traits>

#include "accel/bvh/bvh8_packet_kernel.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/interval_cull.hpp"
#include "accel/bvh/triangle_block.hpp"
#include "accel/simd_float.hpp"
#include "core/intersect.hpp"
#include "core/isa_namespace.hpp"
#include "lancer/accel.hpp"
#include "lancer/packet.hpp"

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

// Rays [first, first + Ops::kWidth) of one of the packet's three-coordinate arrays.
template <class Ops>
[[nodiscard]] block_detail::Vec3v<Ops> load_vec(const float (&soa)[3][kPacketSize], int first) {
    return {Ops::load(&soa[0][first]), Ops::load(&soa[1][first]), Ops::load(&soa[2][first])};
}

// One packet of rays, loaded (load), prepared group by group for the triangle test at its first leaf
// (prepare_group), and answered (store_hits); the leaf tests and the traversal build on it. Ops: the lane
// width of the box and triangle tests.
template <class Ops, class TriangleTestT>
class LoadedPacket {
  protected:
    static constexpr int kLanes = Ops::kWidth;
    static constexpr LaneMask kGroup = (LaneMask{1} << kLanes) - 1;
    static_assert(kPacketSize % kLanes == 0);
    static constexpr int kGroups = kPacketSize / kLanes;
    static constexpr bool kWatertight = std::is_same_v<TriangleTestT, Watertight>;
    using Float = typename Ops::Float;
    using Vec3v = block_detail::Vec3v<Ops>;

  public:
    // Loads rays.size() <= kPacketSize rays; false when the packet cannot be traced together: two valid rays
    // disagree on a direction sign, or a reciprocal direction is not finite (a zero or denormal component,
    // whose NaN plane distances the interval cull does not bound).
    [[nodiscard]] bool load(std::span<const Ray> rays) {
        const Ray* source = rays.data();
        if (rays.size() < static_cast<std::size_t>(kPacketSize)) {
            // A partial packet, padded with rays of zero direction (invalid: no lane of theirs is traced).
            static_assert(std::is_trivially_destructible_v<Ray>);
            auto* padded = reinterpret_cast<Ray*>(padded_rays_.data());
            std::uninitialized_fill(std::uninitialized_copy(rays.begin(), rays.end(), padded),
                                    padded + kPacketSize, Ray{{}, {}, 0.0f, 0.0f});
            source = std::launder(padded);
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

    // Whether the loaded rays' directions lie close enough together for the packet to beat its rays traced
    // one at a time: on every axis the spread of the direction component over the packet is at most
    // `spread` times the largest component's magnitude (a scale-free bound: shadow rays aimed at one light
    // have directions of different lengths). The bounds are those of the node test's intervals, so the
    // test costs a few operations once the packet is loaded. A packet without valid rays agrees.
    [[nodiscard]] bool directions_agree(float spread) const {
        if (valid_ == 0) return true;
        float largest = 0.0f, widest = 0.0f;
        for (std::size_t axis = 0; axis < 3; ++axis) {
            const float a = 1.0f / interval_.inv_lo[axis], b = 1.0f / interval_.inv_hi[axis];
            largest = std::max(largest, std::max(std::abs(a), std::abs(b)));
            widest = std::max(widest, std::abs(a - b));
        }
        return widest <= spread * largest;
    }

    // The largest extent of the box of the loaded rays' origins.
    [[nodiscard]] float origin_width() const {
        float widest = 0.0f;
        for (std::size_t axis = 0; axis < 3; ++axis)
            widest = std::max(widest, std::abs(interval_.exit_origin[axis] - interval_.entry_origin[axis]));
        return widest;
    }

  protected:
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

  private:
    // A group of rays at a time, fields(first, fields) giving the eight fields of the group's lanes: is_valid
    // and SlabRay lane by lane, in the same fp32 operations (the triangle test's RayData waits for a leaf:
    // prepare_group).
    template <class Fields>
    [[nodiscard]] bool load_groups(Fields&& fields_of) {
        const Float infinity = Ops::broadcast(kInfinity), minus_infinity = Ops::broadcast(-kInfinity);
        const Float one = Ops::broadcast(1.0f);
        Float origin_lo[3], origin_hi[3], inv_lo[3], inv_hi[3];
        for (int axis = 0; axis < 3; ++axis) {
            origin_lo[axis] = inv_lo[axis] = infinity;
            origin_hi[axis] = inv_hi[axis] = minus_infinity;
        }
        Float tnear_min = infinity;
        std::array<LaneMask, 3> negative{};
        valid_ = 0;
        groups_ready_ = 0;
        for (int group = 0; group < kGroups; ++group) {
            const int first = group * kLanes;
            Float fields[8];
            fields_of(first, fields);
            const Float origin[3] = {fields[0], fields[1], fields[2]};
            const Float direction[3] = {fields[3], fields[4], fields[5]};
            const Float tnear = fields[6], tfar = fields[7];
            const auto valid = valid_ray_lanes<Ops>(fields);
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
        auto& lanes = code_lanes_[static_cast<std::size_t>(group)];
        unsigned& codes = codes_[static_cast<std::size_t>(group)];
        codes = 0;
        for (int kz = 0; kz < 3; ++kz) {
            lanes[static_cast<std::size_t>(2 * kz)] = kz_lanes[kz] & ~swapped_lanes & valid_lanes;
            lanes[static_cast<std::size_t>(2 * kz + 1)] = kz_lanes[kz] & swapped_lanes & valid_lanes;
        }
        for (int code = 0; code < kPermutations; ++code)
            codes |= (lanes[static_cast<std::size_t>(code)] != 0 ? 1u : 0u) << code;
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

    // load's copies of a partial packet, padded to kPacketSize rays.
    // Raw storage, not Rays: the tracer is made for every packet, and only a batch's partial packet needs
    // these, whose member initialisers were a measurable share of a camera packet's work
    // (docs/accel/packets.md, "Large meshes").
    alignas(Ray) std::array<std::byte, sizeof(Ray) * kPacketSize> padded_rays_;
    RayPacket padded_packet_;

  protected:
    PacketRays packet_;
    PacketInterval interval_;
    std::array<PacketInterval, kGroups> group_intervals_;
    unsigned groups_ready_ = 0;  // bit g: prepare_group(g) has run
    // Per group of lanes, made by prepare_group: the lanes of each watertight axis permutation, and in
    // codes_ bit c when some lane has permutation c (camera rays: one bit), so that a leaf test loops over
    // those alone.
    std::array<std::array<unsigned, kPermutations>, kGroups> code_lanes_;
    std::array<unsigned, kGroups> codes_;
    LaneMask valid_ = 0, alive_ = 0;
    float tlimit_max_ = 0.0f;  // the largest tlimit of the packet
};

}  // namespace
}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
#endif
