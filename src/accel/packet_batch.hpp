// A RayPacket traced as a batch of `Ray` records, for the paths that have no kernel of their own for the
// packet layout: the default Accel::intersect_packet_rays, rays that need conditioning, and a packet
// structure's packets whose rays cannot go together.
#pragma once

#include <cstddef>
#include <span>

#include "lancer/packet.hpp"

namespace lancer {

// Calls trace(rays, hits) with the packet's rays as records and their hit slots, then copies the hits back.
template <class Trace>
void trace_packet_as_batch(const RayPacket& rays, HitPacket& hits, Trace&& trace) {
    // Plain arrays: a std::array of Hit or Ray has a constructor of its own (their members' initialisers),
    // which a compiler may leave out of line under the name every translation unit shares, so that the
    // AVX-512 kernel's copy could serve the AVX2 callers (tests/core/isa_symbols_test.sh; clang does).
    Ray batch[RayPacket::kMaxSize];
    Hit batch_hits[RayPacket::kMaxSize];
    const auto size = static_cast<std::size_t>(rays.size);
    for (int lane = 0; lane < rays.size; ++lane)
        batch[lane] = rays.ray(lane);
    trace(std::span<const Ray>(batch, size), std::span<Hit>(batch_hits, size));
    for (int lane = 0; lane < rays.size; ++lane)
        hits.set(lane, batch_hits[lane]);
}

}  // namespace lancer
