// Coherent packet traversal of the binary SAH BVH (Iehl 2011, "parcours cohérent"): the
// rays of a packet (consecutive rays of the batch, one 8x8 tile of primary rays) go down the tree together.
// Each node's box is tested against all the packet's active rays at once, 8 lanes per AVX2 instruction
// (SIMD across rays, Wald, Slusallek, Benthin & Wagner 2001; masked traversal as in Wald, Boulos & Shirley
// 2007 without their frustum test), and the triangles of a leaf are tested one ray at a time by the same
// code as `bvh`, so that every ray gets the hit `bvh` gives it, bit for bit. Packets whose rays disagree on
// a direction sign go through `bvh` one ray at a time. Design note and measurements: docs/accel/packets.md.
#pragma once

#include <cstdint>

#include "accel/bvh/bvh.hpp"
#include "accel/packet_accel.hpp"

namespace lancer {

class BvhPacketAccel final : public PacketAccel<BvhAccel> {
  public:
    // Rays traced together: one 8x8 tile of `lancer bench`, and at most the 64 bits of a lane mask.
    static constexpr int kPacketSize = 64;

    [[nodiscard]] std::string_view name() const override { return "bvh_packet"; }

  private:
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;
};

}  // namespace lancer
