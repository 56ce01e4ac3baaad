#include "accel/bvh/bvh_packet.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <vector>

#include "accel/bvh/bvh_wide.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/simd_float.hpp"

namespace lancer {
namespace {

constexpr int kPacketSize = BvhPacketAccel::kPacketSize;
constexpr auto kPacketRays = static_cast<std::size_t>(kPacketSize);
using LaneMask = std::uint64_t;  // bit i: ray i of the packet
static_assert(kPacketSize <= 64 && kPacketSize % 8 == 0);

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
// of intersect_box (the same argument as wide.hpp's intersect_children_simd, whose operations these are).
template <class Ops>
[[nodiscard]] unsigned box_lanes(const PacketSlabs& slabs, const BvhNode& node, int first) {
    auto t0 = Ops::load(&slabs.tnear[static_cast<std::size_t>(first)]);
    auto t1 = Ops::load(&slabs.tlimit[static_cast<std::size_t>(first)]);
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const int a = static_cast<int>(axis);
        const float near_bound = slabs.negative[axis] ? node.hi[a] : node.lo[a];
        const float far_bound = slabs.negative[axis] ? node.lo[a] : node.hi[a];
        clip_slab<Ops>(Ops::broadcast(near_bound), Ops::broadcast(far_bound),
                       Ops::load(&slabs.origin[axis][static_cast<std::size_t>(first)]),
                       Ops::load(&slabs.inv_direction[axis][static_cast<std::size_t>(first)]), t0, t1);
    }
    return Ops::bits(Ops::less_equal(t0, t1));
}

#if defined(__AVX2__)
// The wide BVH's 8-wide operations (simd_float.hpp), the same NaN rules.
using PacketLanes = simd::Avx2;
constexpr int kLaneWidth = 8;
#else
// One lane, with the SIMD instructions' NaN rules (second operand when either is NaN).
struct ScalarLane {
    using Float = float;
    static float broadcast(float x) { return x; }
    static float load(const float* p) { return *p; }
    static float sub(float a, float b) { return a - b; }
    static float mul(float a, float b) { return a * b; }
    static float max(float a, float b) { return a > b ? a : b; }
    static float min(float a, float b) { return a < b ? a : b; }
    static float select_if_greater(float a, float b, float if_greater, float otherwise) {
        return a > b ? if_greater : otherwise;
    }
    static bool less_equal(float a, float b) { return a <= b; }
    static unsigned bits(bool lane) { return lane ? 1u : 0u; }
};
using PacketLanes = ScalarLane;
constexpr int kLaneWidth = 1;
#endif

// The rays of `mask` whose search interval [tnear, tlimit] meets the node's box.
[[nodiscard]] LaneMask intersect_box_packet(const PacketSlabs& slabs, const BvhNode& node, LaneMask mask) {
    constexpr LaneMask kGroup = (LaneMask{1} << kLaneWidth) - 1;
    LaneMask result = 0;
    for (int first = 0; first < kPacketSize; first += kLaneWidth) {
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
class BvhPacketTraversal {
  public:
    BvhPacketTraversal(const BvhAccel& bvh, const Geometry& geometry) : bvh_(bvh), geometry_(geometry) {
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
    // `answers` starts as misses; on return answers[i] is ray i's closest hit (Hit) or occlusion (uint8).
    template <bool kAnyHit, bool kCount, class Answer>
    void trace(std::span<Answer> answers, TraversalCounters& counts) {
        const HugePageVector<BvhNode>& nodes = bvh_.nodes();
        const HugePageVector<std::uint32_t>& prim_indices = bvh_.prim_indices();
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
                                answers[lane] = 1;
                                alive &= ~(LaneMask{1} << lane);
                                break;
                            }
                        }
                    } else {
                        Hit& hit = answers[lane];
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

// Cuts the batch into packets of consecutive rays, traces the coherent ones and hands the others to `bvh`.
// Answer: Hit (closest hit) or std::uint8_t (occlusion, kAnyHit).
template <bool kAnyHit, class Answer>
void trace_batch(const BvhAccel& bvh, const Geometry& geometry, TriangleTest test, std::span<const Ray> rays,
                 std::span<Answer> answers, TraversalCounters* counters) {
    dispatch_policies(test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        BvhPacketTraversal<TriangleTestT> tracer(bvh, geometry);
        for_each_packet<kPacketRays, kAnyHit, kCount>(
            rays, answers, bvh, counts,
            [&](std::span<const Ray> packet_rays, std::span<Answer> packet_answers) {
                if (!tracer.load(packet_rays)) return false;
                std::fill(packet_answers.begin(), packet_answers.end(), Answer{});
                tracer.template trace<kAnyHit, kCount>(packet_answers, counts);
                return true;
            });
        if constexpr (kCount) *counters += counts;
    });
}

}  // namespace

void BvhPacketAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                     TraversalCounters* counters) const {
    trace_batch<false>(single_ray_, geometry_, triangle_test_, rays, hits, counters);
}

void BvhPacketAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                    TraversalCounters* counters) const {
    trace_batch<true>(single_ray_, geometry_, triangle_test_, rays, occluded, counters);
}

}  // namespace lancer
