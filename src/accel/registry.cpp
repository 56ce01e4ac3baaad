// The table of structures behind `--accel NAME`: each line a structure's name, summary, factory and the keys
// of its option group (structures that share a group name its keys once, in `lancer info --options`).
#include <algorithm>
#include <functional>
#include <stdexcept>
#include <string>

#include "accel/brute.hpp"
#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh8_packet.hpp"
#include "accel/bvh/bvh_packet.hpp"
#include "accel/bvh/bvh_wide.hpp"
#if LANCER_HAS_EMBREE
#include "accel/embree.hpp"
#endif
#include "accel/grid.hpp"
#include "accel/kdtree.hpp"
#include "accel/octree.hpp"
#include "accel/options.hpp"
#include "accel/plucker/plucker.hpp"
#include "accel/plucker/plucker_packet.hpp"
#include "lancer/accel.hpp"

namespace lancer {
namespace {

struct Entry {
    std::string_view name;
    std::string_view summary;
    std::function<std::unique_ptr<Accel>()> make;
    std::vector<BuildOptionRow> (*option_rows)() = nullptr;
};

const std::vector<Entry>& registry() {
    static const std::vector<Entry> entries = {
        {"brute", "every primitive against every ray: the oracle",
         [] { return std::make_unique<BruteAccel>(); }},
        {"grid", "uniform grid walked by 3D-DDA (Amanatides & Woo 1987)",
         [] { return std::make_unique<GridAccel>(); }, &GridAccel::option_rows},
        {"octree", "classic octree, parametric traversal (Revelles et al. 2000)",
         [] { return std::make_unique<OctreeAccel>(); }, &OctreeAccel::option_rows},
        {"plucker", "Plücker-connected octree walked leaf to leaf (Portalez & Duguet 2016)",
         [] { return std::make_unique<PluckerAccel>(); }, &PluckerAccel::option_rows},
        {"plucker_packet", "the Plücker walk for packets of 64 rays, grouped by leaf",
         [] { return std::make_unique<PluckerPacketAccel>(); }, &PluckerAccel::option_rows},
        {"kdtree", "SAH kd-tree (Wald & Havran 2006)", [] { return std::make_unique<KdTreeAccel>(); },
         &KdTreeAccel::option_rows},
        {"bvh", "binary SAH BVH, binned or full sweep", [] { return std::make_unique<BvhAccel>(); },
         &BvhAccel::option_rows},
        {"bvh_packet", "the binary BVH for packets of 64 coherent rays",
         [] { return std::make_unique<BvhPacketAccel>(); }, &BvhAccel::option_rows},
        {"bvh4", "4-wide BVH collapsed from the binary one, SIMD boxes and triangle blocks",
         [] { return std::make_unique<Bvh4Accel>(); }, &BvhAccel::option_rows},
        {"bvh8", "8-wide BVH collapsed from the binary one, SIMD boxes and triangle blocks",
         [] { return std::make_unique<Bvh8Accel>(); }, &BvhAccel::option_rows},
        {"bvh8_packet",
         "the 8-wide BVH for packets: 64 coherent rays at once, others in streams of one direction octant",
         [] { return std::make_unique<Bvh8PacketAccel>(); }, &BvhAccel::option_rows},
#if LANCER_HAS_EMBREE
        {"embree", "Intel Embree 3, rtcIntersect1 and rtcOccluded1",
         [] { return std::make_unique<EmbreeAccel>(EmbreeCall::Single); }, &EmbreeAccel::option_rows},
        {"embree8", "Intel Embree 3, rtcIntersect8 and rtcOccluded8",
         [] { return std::make_unique<EmbreeAccel>(EmbreeCall::Packet8); }, &EmbreeAccel::option_rows},
        {"embree16", "Intel Embree 3, rtcIntersect16 and rtcOccluded16",
         [] { return std::make_unique<EmbreeAccel>(EmbreeCall::Packet16); }, &EmbreeAccel::option_rows},
        {"embree_stream", "Intel Embree 3, rtcIntersect1M and rtcOccluded1M on streams of rays",
         [] { return std::make_unique<EmbreeAccel>(EmbreeCall::Stream); }, &EmbreeAccel::option_rows},
#endif
    };
    return entries;
}

}  // namespace

std::vector<std::string_view> accel_names() {
    std::vector<std::string_view> names;
    for (const Entry& entry : registry())
        names.push_back(entry.name);
    return names;
}

std::vector<AccelInfo> accel_infos() {
    std::vector<AccelInfo> infos;
    for (const Entry& entry : registry())
        infos.push_back({entry.name, entry.summary});
    return infos;
}

std::vector<BuildOptionRow> option_rows() {
    std::vector<BuildOptionRow> rows;
    for (const Entry& entry : registry()) {
        if (entry.option_rows == nullptr) continue;
        for (BuildOptionRow& row : entry.option_rows()) {
            const bool listed = std::any_of(rows.begin(), rows.end(),
                                            [&](const BuildOptionRow& r) { return r.key == row.key; });
            if (!listed) rows.push_back(std::move(row));
        }
    }
    for (BuildOptionRow& row : shared_option_rows())
        rows.push_back(std::move(row));
    return rows;
}

std::unique_ptr<Accel> make_accel(std::string_view name) {
    for (const Entry& entry : registry()) {
        if (entry.name == name) return entry.make();
    }
    std::string known;
    for (const Entry& entry : registry())
        known += (known.empty() ? "" : ", ") + std::string(entry.name);
    throw std::invalid_argument("unknown acceleration structure '" + std::string(name) +
                                "' (known: " + known + ")");
}

}  // namespace lancer
