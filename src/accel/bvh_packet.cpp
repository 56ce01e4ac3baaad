#include "accel/bvh_packet.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <vector>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include "accel/primitive_test.hpp"

namespace lancer {
namespace {

constexpr int kPacketSize = BvhPacketAccel::kPacketSize;
using LaneMask = std::uint64_t;  // bit i: ray i of the packet
static_assert(kPacketSize <= 64 && kPacketSize % 8 == 0);

// intersect_box's widening of the slab exit (pbrt-v4, Bounds3::IntersectP).
constexpr float kSlabExitWidening = 1.0f + 2.0f * gamma_bound(3);

// The slab-test view of a packet, one array per coordinate so that 8 rays load in one instruction. Unused
// lanes hold zeros and are masked off.
struct PacketSlabs {
    alignas(32) std::array<std::array<float, kPacketSize>, 3> origin{};
    alignas(32) std::array<std::array<float, kPacketSize>, 3> inv_direction{};
    alignas(32) std::array<float, kPacketSize> tnear{};
    alignas(32) std::array<float, kPacketSize> tlimit{};  // the closest hit so far, or tfar
    std::array<std::uint32_t, 3> negative{};              // the packet's direction sign bit on each axis
};

// intersect_box, lane by lane, for a packet whose rays share their direction signs: the near plane of each
// slab is then the same face for every lane, and min/max of the two plane distances become a choice made
// once. The NaN of a zero direction component on a face's plane (0 * inf) leaves the interval unchanged,
// because max_ps / min_ps return their second operand, the interval, when either is NaN: the unbounded slab
// of intersect_box (the same argument as bvh_wide.hpp's wide_detail).
template <class Ops>
[[nodiscard]] unsigned box_lanes(const PacketSlabs& slabs, const BvhNode& node, int first) {
    auto t0 = Ops::load(&slabs.tnear[static_cast<std::size_t>(first)]);
    auto t1 = Ops::load(&slabs.tlimit[static_cast<std::size_t>(first)]);
    const auto widening = Ops::broadcast(kSlabExitWidening);
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const int a = static_cast<int>(axis);
        const float near_bound = slabs.negative[axis] ? node.hi[a] : node.lo[a];
        const float far_bound = slabs.negative[axis] ? node.lo[a] : node.hi[a];
        const auto origin = Ops::load(&slabs.origin[axis][static_cast<std::size_t>(first)]);
        const auto inv_direction = Ops::load(&slabs.inv_direction[axis][static_cast<std::size_t>(first)]);
        const auto near_plane = Ops::mul(Ops::sub(Ops::broadcast(near_bound), origin), inv_direction);
        const auto far_plane =
            Ops::mul(Ops::mul(Ops::sub(Ops::broadcast(far_bound), origin), inv_direction), widening);
        t0 = Ops::max(near_plane, t0);
        t1 = Ops::min(far_plane, t1);
    }
    return Ops::mask_less_equal(t0, t1);
}

#if defined(__AVX2__)
struct Avx2Lanes {
    static constexpr int kWidth = 8;
    static __m256 broadcast(float x) { return _mm256_set1_ps(x); }
    static __m256 load(const float* p) { return _mm256_load_ps(p); }
    static __m256 sub(__m256 a, __m256 b) { return _mm256_sub_ps(a, b); }
    static __m256 mul(__m256 a, __m256 b) { return _mm256_mul_ps(a, b); }
    static __m256 max(__m256 a, __m256 b) { return _mm256_max_ps(a, b); }
    static __m256 min(__m256 a, __m256 b) { return _mm256_min_ps(a, b); }
    // Ordered, non-signalling: a NaN compares false, as t0 <= t1 does in intersect_box.
    static unsigned mask_less_equal(__m256 a, __m256 b) {
        return static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)));
    }
};
using PacketLanes = Avx2Lanes;
#else
// One lane, with the SIMD instructions' NaN rules (second operand when either is NaN).
struct ScalarLane {
    static constexpr int kWidth = 1;
    static float broadcast(float x) { return x; }
    static float load(const float* p) { return *p; }
    static float sub(float a, float b) { return a - b; }
    static float mul(float a, float b) { return a * b; }
    static float max(float a, float b) { return a > b ? a : b; }
    static float min(float a, float b) { return a < b ? a : b; }
    static unsigned mask_less_equal(float a, float b) { return a <= b ? 1u : 0u; }
};
using PacketLanes = ScalarLane;
#endif

// The rays of `mask` whose search interval [tnear, tlimit] meets the node's box.
[[nodiscard]] LaneMask intersect_box_packet(const PacketSlabs& slabs, const BvhNode& node, LaneMask mask) {
    constexpr int kWidth = PacketLanes::kWidth;
    constexpr LaneMask kGroup = (LaneMask{1} << kWidth) - 1;
    LaneMask result = 0;
    for (int first = 0; first < kPacketSize; first += kWidth) {
        const LaneMask lanes = (mask >> first) & kGroup;
        if (lanes == 0) continue;
        result |= (static_cast<LaneMask>(box_lanes<PacketLanes>(slabs, node, first)) & lanes) << first;
    }
    return result;
}

struct PacketStackEntry {
    std::uint32_t node;
    LaneMask rays;  // the rays that met the parent; retested against this node's box when it is popped
};

// One packet: its rays prepared for the triangle test and laid out for the box test.
template <class TriangleTestT>
class PacketTracer {
  public:
    PacketTracer(const BvhAccel& bvh, const Geometry& geometry) : bvh_(bvh), geometry_(geometry) {
        prepared_.reserve(kPacketSize);
    }

    // Loads rays.size() <= kPacketSize rays; false when two valid rays disagree on a direction sign (the
    // packet would visit the union of their paths: `bvh` then traces them one at a time).
    [[nodiscard]] bool load(std::span<const Ray> rays) {
        prepared_.clear();
        valid_ = 0;
        std::array<std::uint32_t, 3> signs{};
        for (std::size_t i = 0; i < rays.size(); ++i) {
            const Ray& ray = rays[i];
            prepared_.emplace_back(ray);
            if (!is_valid(ray)) continue;
            std::array<std::uint32_t, 3> ray_signs{};
            for (std::size_t axis = 0; axis < 3; ++axis)
                ray_signs[axis] = std::signbit(ray.direction[static_cast<int>(axis)]) ? 1u : 0u;
            if (valid_ == 0)
                signs = ray_signs;
            else if (ray_signs != signs)
                return false;
            valid_ |= LaneMask{1} << i;
            const SlabRay slab(ray);  // the reciprocals intersect_box uses
            for (std::size_t axis = 0; axis < 3; ++axis) {
                slabs_.origin[axis][i] = slab.origin[static_cast<int>(axis)];
                slabs_.inv_direction[axis][i] = slab.inv_direction[static_cast<int>(axis)];
            }
            slabs_.tnear[i] = ray.tnear;
            slabs_.tlimit[i] = ray.tfar;
        }
        slabs_.negative = signs;
        return true;
    }

    // Front to back as `bvh`: the near child (by the packet's direction sign on the split axis) first, the
    // far one pushed with the rays that met the parent. kAnyHit: a ray leaves the packet at its first hit.
    // On return best[i] is ray i's closest hit (kAnyHit false) or occluded[i] says whether it hit anything.
    template <bool kAnyHit, bool kCount>
    void trace(std::span<Hit> best, std::span<std::uint8_t> occluded, TraversalCounters& counts) {
        const std::vector<BvhNode>& nodes = bvh_.nodes();
        const std::vector<std::uint32_t>& prim_indices = bvh_.prim_indices();
        LaneMask alive = valid_;
        if (nodes.empty() || alive == 0) return;
        std::array<PacketStackEntry, BvhAccel::kMaxDepth + 1> stack;
        int stack_size = 0;
        std::uint32_t current = 0;
        LaneMask rays = alive;
        while (true) {
            if constexpr (kAnyHit) rays &= alive;
            const BvhNode& node = nodes[current];
            rays = rays == 0 ? 0 : intersect_box_packet(slabs_, node, rays);
            if (rays != 0) {
                if constexpr (kCount) counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(rays));
                if (!node.is_leaf()) {
                    const std::uint32_t first = current + 1, second = node.offset;
                    const bool second_is_near = slabs_.negative[node.axis] != 0;
                    stack[static_cast<std::size_t>(stack_size++)] = {second_is_near ? first : second, rays};
                    current = second_is_near ? second : first;
                    continue;
                }
                if constexpr (kCount)
                    counts.prims_tested += static_cast<std::uint64_t>(node.prim_count) *
                                           static_cast<std::uint64_t>(std::popcount(rays));
                for (LaneMask lanes = rays; lanes != 0; lanes &= lanes - 1) {
                    const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
                    const PreparedRay<TriangleTestT>& prepared = prepared_[lane];
                    if constexpr (kAnyHit) {
                        for (std::uint32_t i = node.offset; i < node.offset + node.prim_count; ++i) {
                            if (occludes(geometry_, prim_indices[i], prepared)) {
                                occluded[lane] = 1;
                                alive &= ~(LaneMask{1} << lane);
                                break;
                            }
                        }
                    } else {
                        Hit& hit = best[lane];
                        for (std::uint32_t i = node.offset; i < node.offset + node.prim_count; ++i)
                            intersect_primitive(geometry_, prim_indices[i], prepared, hit);
                        if (hit.hit()) slabs_.tlimit[lane] = hit.t;
                    }
                }
            }
            if (stack_size == 0) return;
            const PacketStackEntry& entry = stack[static_cast<std::size_t>(--stack_size)];
            current = entry.node;
            rays = entry.rays;
        }
    }

  private:
    const BvhAccel& bvh_;
    const Geometry& geometry_;
    std::vector<PreparedRay<TriangleTestT>> prepared_;
    PacketSlabs slabs_;
    LaneMask valid_ = 0;
};

// Cuts the batch into packets of consecutive rays: coherent(tracer, first, count) traces a loaded coherent
// packet, single(first, count) the rays of an incoherent one through `bvh`.
template <class TriangleTestT, class Coherent, class Single>
void for_each_packet(const BvhAccel& bvh, const Geometry& geometry, std::span<const Ray> rays,
                     Coherent&& coherent, Single&& single) {
    PacketTracer<TriangleTestT> tracer(bvh, geometry);
    for (std::size_t first = 0; first < rays.size(); first += kPacketSize) {
        const std::size_t count = std::min<std::size_t>(kPacketSize, rays.size() - first);
        if (tracer.load(rays.subspan(first, count)))
            coherent(tracer, first, count);
        else
            single(first, count);
    }
}

}  // namespace

void BvhPacketAccel::build(const Geometry& geometry, const BuildOptions& options) {
    bvh_.build(geometry, options);
    geometry_ = geometry;
    triangle_test_ = options.triangle_test;
}

void BvhPacketAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                     TraversalCounters* counters) const {
    dispatch_policies(triangle_test_, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        for_each_packet<TriangleTestT>(
            bvh_, geometry_, rays,
            [&](PacketTracer<TriangleTestT>& tracer, std::size_t first, std::size_t count) {
                const std::span<Hit> packet_hits = hits.subspan(first, count);
                std::fill(packet_hits.begin(), packet_hits.end(), Hit{});
                tracer.template trace<false, kCount>(packet_hits, {}, counts);
                if constexpr (kCount) counts.rays += count;
            },
            [&](std::size_t first, std::size_t count) {
                bvh_.intersect(rays.subspan(first, count), hits.subspan(first, count),
                               kCount ? &counts : nullptr);
            });
        if constexpr (kCount) *counters += counts;
    });
}

void BvhPacketAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                    TraversalCounters* counters) const {
    dispatch_policies(triangle_test_, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        for_each_packet<TriangleTestT>(
            bvh_, geometry_, rays,
            [&](PacketTracer<TriangleTestT>& tracer, std::size_t first, std::size_t count) {
                const std::span<std::uint8_t> packet_occluded = occluded.subspan(first, count);
                std::fill(packet_occluded.begin(), packet_occluded.end(), std::uint8_t{0});
                tracer.template trace<true, kCount>({}, packet_occluded, counts);
                if constexpr (kCount) counts.rays += count;
            },
            [&](std::size_t first, std::size_t count) {
                bvh_.occluded(rays.subspan(first, count), occluded.subspan(first, count),
                              kCount ? &counts : nullptr);
            });
        if constexpr (kCount) *counters += counts;
    });
}

}  // namespace lancer
