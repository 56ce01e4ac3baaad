#include "accel/plucker/plucker_packet.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <vector>

#include "accel/plucker/leaf_block.hpp"
#include "accel/plucker/walk.hpp"
#include "accel/primitive_intersect.hpp"

namespace lancer {
namespace {

using plucker::PluckerLayout;

constexpr int kPacketSize = PluckerPacketAccel::kPacketSize;
using LaneMask = std::uint64_t;  // bit i: ray i of the packet
static_assert(kPacketSize <= 64);

// The primitive tests a leaf costs a group: each of its primitives against each ray.
[[nodiscard]] std::uint64_t group_tests(const std::uint32_t* record, LaneMask group) {
    return static_cast<std::uint64_t>(record[plucker::kTriangleCount]) *
           static_cast<std::uint64_t>(std::popcount(group));
}

// The walk of `plucker` (walk.hpp, section 4.2.3) for the rays of `valid`, grouped by leaf. Each group is
// the rays whose current leaf is the first walking ray's; visit_leaf(record, group, limits) tests them and
// lowers limits[i], the end of ray i's search interval (below tnear ends its walk, as in walk()); then each
// ray of the group takes its own EXIT-FACE and NEIGHBOR steps.
template <bool kBalanced, bool kStoredBoxes, bool kCount, class TriangleTestT, class LeafVisitor>
void walk_packet(const plucker::PluckerView& view, const std::vector<PreparedRay<TriangleTestT>>& prepared,
                 LaneMask valid, LeafVisitor&& visit_leaf, TraversalCounters& counts) {
    using Walker = plucker::Walker<kBalanced, kStoredBoxes>;
    const Walker walker(view, plucker::kTables);
    // The inner cells a link descends, counted as the single-ray walk counts them.
    plucker::CellCounter<kCount> inner_cells{counts};
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
        visit_leaf(view.cells + address, group, limits);
        // EXIT-FACE, NEIGHBOR
        for (LaneMask lanes = group; lanes != 0; lanes &= lanes - 1) {
            const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
            if (limits[lane] < prepared[lane].ray.tnear ||
                !walker.advance(states[lane], walker.exit(states[lane]), limits[lane], inner_cells))
                walking &= ~(LaneMask{1} << lane);
            addresses[lane] = states[lane].address;
        }
    }
}

// Cuts the batch into packets of consecutive rays and calls
// packet.template operator()<kCount, kBalanced, kStoredBoxes>(prepared, valid, first, count, counts) for
// each, with the policies and the layout's variant dispatched once per batch.
template <class Packet>
void for_each_packet(const PluckerLayout& layout, TriangleTest test, std::span<const Ray> rays,
                     TraversalCounters* counters, Packet&& packet) {
    dispatch_policies(test, counters != nullptr, [&]<class TriangleTestT, bool kCount>() {
        TraversalCounters counts;
        plucker::dispatch_layout(layout.options, [&]<bool kBalanced, bool kStoredBoxes>() {
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
                packet.template operator()<kCount, kBalanced, kStoredBoxes>(prepared, valid, first, count,
                                                                            counts);
            }
        });
        if constexpr (kCount) {
            counts.rays = rays.size();
            *counters += counts;
        }
    });
}

}  // namespace

void PluckerPacketAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                         TraversalCounters* counters) const {
    const PluckerLayout& layout = single_ray_.layout();
    const plucker::PluckerView view = plucker::view_of(layout);
    for_each_packet(
        layout, triangle_test_, rays, counters,
        [&]<bool kCount, bool kBalanced, bool kStoredBoxes>(const auto& prepared, LaneMask valid,
                                                            std::size_t first, std::size_t count,
                                                            TraversalCounters& counts) {
            std::array<Hit, kPacketSize> best;
            walk_packet<kBalanced, kStoredBoxes, kCount>(
                view, prepared, valid,
                [&](const std::uint32_t* record, LaneMask group, std::array<float, kPacketSize>& limits) {
                    if constexpr (kCount) counts.prims_tested += group_tests(record, group);
                    // Each block gathered once for the whole group, then tested against each of its rays.
                    plucker::for_each_leaf_block(layout, record, [&](const plucker::LeafBlock& block) {
                        for (LaneMask lanes = group; lanes != 0; lanes &= lanes - 1) {
                            const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
                            intersect_block(geometry_, block,
                                            plucker::leaf_block_ray(prepared[lane], geometry_), best[lane]);
                            if (best[lane].hit()) limits[lane] = best[lane].t;
                        }
                        return false;
                    });
                },
                counts);
            std::copy_n(best.begin(), count, hits.begin() + static_cast<std::ptrdiff_t>(first));
        });
}

void PluckerPacketAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                        TraversalCounters* counters) const {
    const PluckerLayout& layout = single_ray_.layout();
    const plucker::PluckerView view = plucker::view_of(layout);
    for_each_packet(
        layout, triangle_test_, rays, counters,
        [&]<bool kCount, bool kBalanced, bool kStoredBoxes>(const auto& prepared, LaneMask valid,
                                                            std::size_t first, std::size_t count,
                                                            TraversalCounters& counts) {
            LaneMask hit = 0;
            walk_packet<kBalanced, kStoredBoxes, kCount>(
                view, prepared, valid,
                [&](const std::uint32_t* record, LaneMask group, std::array<float, kPacketSize>& limits) {
                    if constexpr (kCount) counts.prims_tested += group_tests(record, group);
                    plucker::for_each_leaf_block(layout, record, [&](const plucker::LeafBlock& block) {
                        for (LaneMask lanes = group & ~hit; lanes != 0; lanes &= lanes - 1) {
                            const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
                            if (occludes_block(geometry_, block,
                                               plucker::leaf_block_ray(prepared[lane], geometry_))) {
                                hit |= LaneMask{1} << lane;
                                limits[lane] = -kInfinity;  // any hit ends the ray's walk
                            }
                        }
                        return false;
                    });
                },
                counts);
            for (std::size_t lane = 0; lane < count; ++lane)
                occluded[first + lane] = (hit >> lane) & 1u;
        });
}

}  // namespace lancer
