// Packets of rays walked leaf to leaf through the Plücker-connected octree (Iehl 2011's "parcours cohérent"
// applied to Portalez & Duguet's walk). Every ray keeps its own walk state; the walk repeatedly takes
// the leaf of the first ray still walking, tests all the rays standing in that same leaf together (each
// triangle loaded once for all of them), then moves each of them to its next leaf by its own EXIT-FACE and
// NEIGHBOR steps. A ray therefore visits exactly the leaves, with exactly the search intervals, of its walk
// in `plucker`, and gets the same hit bit for bit; rays that part ways simply form smaller groups, so an
// incoherent packet needs no fallback. Design note and measurements: docs/accel/packets.md.
#pragma once

#include <cstdint>

#include "accel/packet_accel.hpp"
#include "accel/plucker/plucker.hpp"

namespace lancer {

class PluckerPacketAccel final : public PacketAccel<PluckerAccel> {
  public:
    // Rays walked together: one 8x8 tile of `lancer bench`, and the 64 bits of a lane mask.
    static constexpr int kPacketSize = 64;

    [[nodiscard]] std::string_view name() const override { return "plucker_packet"; }

  private:
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;
};

}  // namespace lancer
