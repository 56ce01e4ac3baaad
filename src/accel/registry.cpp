// The table of structures behind `--accel NAME`.
#include <functional>
#include <stdexcept>
#include <string>

#include "accel/brute.hpp"
#include "accel/bvh/bvh.hpp"
#include "accel/bvh/packet.hpp"
#include "accel/bvh/wide.hpp"
#include "accel/bvh/wide_packet.hpp"
#if LANCER_HAS_EMBREE
#include "accel/embree.hpp"
#endif
#include "accel/grid.hpp"
#include "accel/kdtree.hpp"
#include "accel/octree.hpp"
#include "accel/plucker/packet.hpp"
#include "accel/plucker/plucker.hpp"
#include "lancer/accel.hpp"

namespace lancer {
namespace {

struct Entry {
    std::string_view name;
    std::function<std::unique_ptr<Accel>()> make;
};

const std::vector<Entry>& registry() {
    static const std::vector<Entry> entries = {
        {"brute", [] { return std::make_unique<BruteAccel>(); }},
        {"grid", [] { return std::make_unique<GridAccel>(); }},
        {"octree", [] { return std::make_unique<OctreeAccel>(); }},
        {"plucker", [] { return std::make_unique<PluckerAccel>(); }},
        {"plucker_packet", [] { return std::make_unique<PluckerPacketAccel>(); }},
        {"kdtree", [] { return std::make_unique<KdTreeAccel>(); }},
        {"bvh", [] { return std::make_unique<BvhAccel>(); }},
        {"bvh_packet", [] { return std::make_unique<BvhPacketAccel>(); }},
        {"bvh4", [] { return std::make_unique<Bvh4Accel>(); }},
        {"bvh8", [] { return std::make_unique<Bvh8Accel>(); }},
        {"bvh8_packet", [] { return std::make_unique<WidePacketAccel>(); }},
#if LANCER_HAS_EMBREE
        {"embree", [] { return std::make_unique<EmbreeAccel>(1); }},
        {"embree8", [] { return std::make_unique<EmbreeAccel>(8); }},
        {"embree16", [] { return std::make_unique<EmbreeAccel>(16); }},
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
