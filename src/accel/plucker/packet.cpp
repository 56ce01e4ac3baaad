#include "accel/plucker/packet.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <type_traits>
#include <vector>

#include "accel/plucker/walk.hpp"
#include "accel/plucker/watertight_lanes.hpp"
#include "accel/primitive_test.hpp"

namespace lancer {
namespace {

using plucker::PluckerLayout;
using plucker::PluckerPrimitive;

constexpr int kPacketSize = PluckerPacketAccel::kPacketSize;
using LaneMask = std::uint64_t;  // bit i: ray i of the packet
static_assert(kPacketSize <= 64);

// Calls body.template operator()<kBalanced>(boxes) with the layout's variant, as PluckerAccel does.
template <class Body>
void dispatch_layout(const PluckerLayout& layout, Body&& body) {
    const plucker::StoredBoxes stored{layout.boxes.data()};
    const plucker::ComputedBoxes computed{layout.cube};
    if (layout.options.balanced) {
        layout.options.stored_boxes ? body.template operator()<true>(stored)
                                    : body.template operator()<true>(computed);
    } else {
        layout.options.stored_boxes ? body.template operator()<false>(stored)
                                    : body.template operator()<false>(computed);
    }
}

// A primitive of a leaf record against one ray within [tnear, tfar]: the test of `plucker`'s leaf loop.
template <class TriangleTestT>
[[nodiscard]] bool intersect_leaf_primitive(const PluckerLayout& layout, const Geometry& geometry,
                                            const PluckerPrimitive& primitive,
                                            const PreparedRay<TriangleTestT>& prepared, float tfar,
                                            TriangleHit& candidate) {
    const Ray& ray = prepared.ray;
    return primitive.prim < layout.triangle_count
               ? TriangleTestT::intersect(prepared.triangle_data, primitive.triangle, ray.tnear, tfar,
                                          candidate)
               : intersect_sphere(ray, geometry.spheres[primitive.prim - layout.triangle_count], ray.tnear,
                                  tfar, candidate);
}

// LEAF for a group, closest hit: every primitive of the leaf against every ray of the group, and each ray's
// closest hit and search interval updated. With the watertight test and AVX2, the rays of the group that
// share the first one's ray-space axes are tested 8 at a time (watertight_lanes.hpp, the scalar test's bits);
// the others, spheres and the lanes the SIMD test leaves to the scalar code go one ray at a time.
template <class TriangleTestT>
class ClosestInLeaf {
  public:
    ClosestInLeaf(const PluckerLayout& layout, const Geometry& geometry)
        : layout_(layout), geometry_(geometry) {}

    // A new packet: every ray misses so far.
    void start(const std::vector<PreparedRay<TriangleTestT>>& prepared) {
        prepared_ = &prepared;
        best_.fill(Hit{});
    }
    [[nodiscard]] const std::array<Hit, kPacketSize>& best() const { return best_; }

    void operator()(const PluckerPrimitive* leaf, std::uint32_t primitive_count, LaneMask group,
                    std::array<float, kPacketSize>& limits) {
        const std::vector<PreparedRay<TriangleTestT>>& prepared = *prepared_;
        const auto test_one = [&](const PluckerPrimitive& primitive, std::size_t lane) {
            TriangleHit candidate;
            const auto prim = static_cast<std::int32_t>(primitive.prim);
            if (intersect_leaf_primitive(layout_, geometry_, primitive, prepared[lane], limits[lane],
                                         candidate) &&
                closer(candidate.t, prim, best_[lane])) {
                best_[lane] = {candidate.t, prim, candidate.u, candidate.v};
                limits[lane] = candidate.t;
            }
        };
        LaneMask one_at_a_time = group;
#if defined(__AVX2__)
        int chunk_count = 0;
        if constexpr (std::is_same_v<TriangleTestT, Watertight>) {
            if (std::popcount(group) >= kMinSimdGroup)
                one_at_a_time = load_chunks(group, limits, chunk_count);
        }
#endif
        for (std::uint32_t r = 0; r < primitive_count; ++r) {
            const PluckerPrimitive& primitive = leaf[r];
#if defined(__AVX2__)
            if (chunk_count > 0) {
                if (primitive.prim < layout_.triangle_count) {
                    test_chunks(primitive, chunk_count, limits, test_one);
                } else {
                    for (LaneMask lanes = group & ~one_at_a_time; lanes != 0; lanes &= lanes - 1)
                        test_one(primitive, static_cast<std::size_t>(std::countr_zero(lanes)));
                }
            }
#endif
            for (LaneMask lanes = one_at_a_time; lanes != 0; lanes &= lanes - 1)
                test_one(primitive, static_cast<std::size_t>(std::countr_zero(lanes)));
        }
    }

  private:
#if defined(__AVX2__)
    // Below this many rays in a group, 8-wide tests would mostly compute empty lanes.
    static constexpr int kMinSimdGroup = 3;

    // Packs the group's rays with the first one's axes into chunks of 8; returns the rays left over.
    LaneMask load_chunks(LaneMask group, const std::array<float, kPacketSize>& limits, int& chunk_count) {
        const std::vector<PreparedRay<TriangleTestT>>& prepared = *prepared_;
        const auto& first = prepared[static_cast<std::size_t>(std::countr_zero(group))].triangle_data;
        LaneMask left = 0;
        for (LaneMask lanes = group; lanes != 0; lanes &= lanes - 1) {
            const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
            const auto& data = prepared[lane].triangle_data;
            if (data.kx != first.kx || data.ky != first.ky || data.kz != first.kz) {
                left |= LaneMask{1} << lane;
                continue;
            }
            if (chunk_count == 0 ||
                chunks_[static_cast<std::size_t>(chunk_count - 1)].count == plucker::WatertightLanes::kWidth)
                chunks_[static_cast<std::size_t>(chunk_count++)].count = 0;
            chunks_[static_cast<std::size_t>(chunk_count - 1)].add(static_cast<std::uint8_t>(lane), data,
                                                                   prepared[lane].ray.tnear, limits[lane]);
        }
        return left;
    }

    // The chunks' interval ends stay those of the leaf's start: a hit past a ray's closest one is accepted by
    // the test and then refused by closer(), as the scalar test with the tighter tfar would refuse it.
    template <class TestOne>
    void test_chunks(const PluckerPrimitive& primitive, int chunk_count,
                     std::array<float, kPacketSize>& limits, TestOne& test_one) {
        const auto prim = static_cast<std::int32_t>(primitive.prim);
        for (int c = 0; c < chunk_count; ++c) {
            const plucker::WatertightLanes& chunk = chunks_[static_cast<std::size_t>(c)];
            const plucker::WatertightLanes::Result result = chunk.intersect(primitive.triangle);
            for (unsigned bits = result.hits; bits != 0; bits &= bits - 1) {
                const auto k = static_cast<std::size_t>(std::countr_zero(bits));
                const std::size_t lane = chunk.lane[k];
                if (closer(result.t[k], prim, best_[lane])) {
                    best_[lane] = {result.t[k], prim, result.u[k], result.v[k]};
                    limits[lane] = result.t[k];
                }
            }
            for (unsigned bits = result.exact; bits != 0; bits &= bits - 1)
                test_one(primitive, chunk.lane[static_cast<std::size_t>(std::countr_zero(bits))]);
        }
    }

    std::array<plucker::WatertightLanes, kPacketSize / plucker::WatertightLanes::kWidth> chunks_;
#endif
    const PluckerLayout& layout_;
    const Geometry& geometry_;
    const std::vector<PreparedRay<TriangleTestT>>* prepared_ = nullptr;
    std::array<Hit, kPacketSize> best_;
};

// The walk of `plucker` (walk.hpp, section 4.2.3) for the rays of `valid`, grouped by leaf. Each group is
// the rays whose current leaf is the first walking ray's; visit_leaf(record, group, limits) tests them and
// lowers limits[i], the end of ray i's search interval (below tnear ends its walk, as in walk()); then each
// ray of the group takes its own EXIT-FACE and NEIGHBOR steps.
template <bool kBalanced, bool kCount, class Boxes, class TriangleTestT, class LeafVisitor>
void walk_packet(const PluckerLayout& layout, const Boxes& boxes,
                 const std::vector<PreparedRay<TriangleTestT>>& prepared, LaneMask valid,
                 LeafVisitor&& visit_leaf, TraversalCounters& counts) {
    using Walker = plucker::Walker<kBalanced, Boxes>;
    const Walker walker(layout, boxes);
    std::array<typename Walker::State, kPacketSize> states;
    std::array<float, kPacketSize> limits{};
    // Each ray's current leaf, side by side so that finding a group is one pass of compares.
    std::array<std::uint32_t, kPacketSize> addresses{};
    LaneMask walking = 0;
    // ENTRY, ray by ray: the rays of a tile share their origin but enter the root at different points.
    for (LaneMask lanes = valid; lanes != 0; lanes &= lanes - 1) {
        const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
        if (!walker.enter(prepared[lane].ray, states[lane])) continue;
        walking |= LaneMask{1} << lane;
        limits[lane] = prepared[lane].ray.tfar;
        addresses[lane] = states[lane].address;
    }
    while (walking != 0) {
        const std::uint32_t address = addresses[static_cast<std::size_t>(std::countr_zero(walking))];
        LaneMask same_leaf = 0;
        for (std::size_t lane = 0; lane < kPacketSize; ++lane)
            same_leaf |= static_cast<LaneMask>(addresses[lane] == address) << lane;
        const LaneMask group = same_leaf & walking;
        // LEAF
        if constexpr (kCount) counts.nodes_visited += static_cast<std::uint64_t>(std::popcount(group));
        visit_leaf(layout.cells.data() + address, group, limits);
        // EXIT-FACE, NEIGHBOR
        for (LaneMask lanes = group; lanes != 0; lanes &= lanes - 1) {
            const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
            if (limits[lane] < prepared[lane].ray.tnear ||
                !walker.template advance<kCount>(states[lane], limits[lane], &counts))
                walking &= ~(LaneMask{1} << lane);
            addresses[lane] = states[lane].address;
        }
    }
}

// Cuts the batch into packets of consecutive rays and calls
// packet.template operator()<kBalanced>(boxes, prepared, valid, first, count) for each, with the policies and
// the layout's variant dispatched once per batch.
template <class TriangleTestT, class Packet>
void for_each_packet(const PluckerLayout& layout, std::span<const Ray> rays, Packet&& packet) {
    dispatch_layout(layout, [&]<bool kBalanced>(const auto& boxes) {
        std::vector<PreparedRay<TriangleTestT>> prepared;
        prepared.reserve(kPacketSize);
        for (std::size_t first = 0; first < rays.size(); first += kPacketSize) {
            const std::size_t count = std::min<std::size_t>(kPacketSize, rays.size() - first);
            prepared.clear();
            LaneMask valid = 0;
            for (std::size_t lane = 0; lane < count; ++lane) {
                prepared.emplace_back(rays[first + lane]);
                if (is_valid(rays[first + lane])) valid |= LaneMask{1} << lane;
            }
            packet.template operator()<kBalanced>(boxes, prepared, valid, first, count);
        }
    });
}

}  // namespace

void PluckerPacketAccel::build(const Geometry& geometry, const BuildOptions& options) {
    plucker_.build(geometry, options);
    geometry_ = geometry;
    triangle_test_ = options.triangle_test;
}

void PluckerPacketAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                         TraversalCounters* counters) const {
    const PluckerLayout& layout = plucker_.layout();
    dispatch_policies(triangle_test_, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        ClosestInLeaf<TriangleTestT> closest(layout, geometry_);
        for_each_packet<TriangleTestT>(
            layout, rays,
            [&]<bool kBalanced>(const auto& boxes, const auto& prepared, LaneMask valid, std::size_t first,
                                std::size_t count) {
                closest.start(prepared);
                walk_packet<kBalanced, kCount>(
                    layout, boxes, prepared, valid,
                    [&](const std::uint32_t* record, LaneMask group, std::array<float, kPacketSize>& limits) {
                        const std::uint32_t primitive_count = record[plucker::kTriangleCount];
                        if constexpr (kCount)
                            counts.prims_tested += static_cast<std::uint64_t>(primitive_count) *
                                                   static_cast<std::uint64_t>(std::popcount(group));
                        closest(layout.primitives.data() + record[plucker::kTriangleOffset], primitive_count,
                                group, limits);
                    },
                    counts);
                std::copy_n(closest.best().begin(), count, hits.begin() + static_cast<std::ptrdiff_t>(first));
                if constexpr (kCount) counts.rays += count;
            });
        if constexpr (kCount) *counters += counts;
    });
}

void PluckerPacketAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                        TraversalCounters* counters) const {
    const PluckerLayout& layout = plucker_.layout();
    dispatch_policies(triangle_test_, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        for_each_packet<TriangleTestT>(
            layout, rays,
            [&]<bool kBalanced>(const auto& boxes, const auto& prepared, LaneMask valid, std::size_t first,
                                std::size_t count) {
                LaneMask hit = 0;
                walk_packet<kBalanced, kCount>(
                    layout, boxes, prepared, valid,
                    [&](const std::uint32_t* record, LaneMask group, std::array<float, kPacketSize>& limits) {
                        const std::uint32_t primitive_count = record[plucker::kTriangleCount];
                        const PluckerPrimitive* leaf =
                            layout.primitives.data() + record[plucker::kTriangleOffset];
                        for (LaneMask lanes = group; lanes != 0; lanes &= lanes - 1) {
                            const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
                            for (std::uint32_t r = 0; r < primitive_count; ++r) {
                                if constexpr (kCount) ++counts.prims_tested;
                                TriangleHit candidate;
                                if (intersect_leaf_primitive(layout, geometry_, leaf[r], prepared[lane],
                                                             prepared[lane].ray.tfar, candidate)) {
                                    hit |= LaneMask{1} << lane;
                                    limits[lane] = -kInfinity;  // any hit ends the ray's walk
                                    break;
                                }
                            }
                        }
                    },
                    counts);
                for (std::size_t lane = 0; lane < count; ++lane)
                    occluded[first + lane] = (hit >> lane) & 1u;
                if constexpr (kCount) counts.rays += count;
            });
        if constexpr (kCount) *counters += counts;
    });
}

}  // namespace lancer
