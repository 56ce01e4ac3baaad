// A RayPacket traced as a batch of `Ray` records, for the paths that have no kernel of their own for the
// packet layout: the default Accel::intersect_packet_rays, rays that need conditioning, and a packet
// structure's packets whose rays cannot go together.
#pragma once

#include <array>
#include <cstddef>
#include <span>

#include "lancer/packet.hpp"

namespace lancer {

// Calls trace(rays, hits) with the packet's rays as records and their hit slots, then copies the hits back.
template <class Trace>
void trace_packet_as_batch(const RayPacket& rays, HitPacket& hits, Trace&& trace) {
    std::array<Ray, RayPacket::kMaxSize> batch;
    std::array<Hit, RayPacket::kMaxSize> batch_hits;
    const auto size = static_cast<std::size_t>(rays.size);
    for (int lane = 0; lane < rays.size; ++lane)
        batch[static_cast<std::size_t>(lane)] = rays.ray(lane);
    trace(std::span<const Ray>(batch.data(), size), std::span<Hit>(batch_hits.data(), size));
    for (int lane = 0; lane < rays.size; ++lane)
        hits.set(lane, batch_hits[static_cast<std::size_t>(lane)]);
}

}  // namespace lancer
