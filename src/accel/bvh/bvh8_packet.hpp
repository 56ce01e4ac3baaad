// Large-packet traversal of the 8-wide BVH (docs/accel/packets.md): 64 consecutive rays (one 8x8 tile of
// primary rays) walk `bvh8` together. Each node culls its 8 children for the whole packet at once with
// interval arithmetic on the packet's origins and reciprocal directions (Overbeck, Ramamoorthi & Mark,
// "Large Ray Packets for Real-time Whitted Ray Tracing", RT 2008; Fuetterling et al., "Efficient Ray Tracing
// Kernels for Modern CPU Architectures", JCGT 2015); a child that survives is tested against the packet's
// active rays, 8 (AVX2) or 16 (AVX-512) per instruction, when it is visited; and a leaf tests each triangle
// against the active rays with the same lane kernels as bvh8's triangle blocks (triangle_block.hpp), so every
// ray gets bvh8's hit, bit for bit. The rays of a packet that disagree on a direction sign, have a direction
// component whose reciprocal is not finite, or (in a batch) directions or origins that spread too far, join
// instead the streams of 64 (or 32) rays of one direction octant that walk bvh8 together, each ray testing
// the boxes of the nodes the stream visits (bvh8_packet_stream.hpp). docs/accel/packets.md and
// docs/accel/stream.md have the design notes and measurements.
#pragma once

#include <cstdint>

#include "accel/bvh/bvh8_packet_kernel.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/packet_accel.hpp"

namespace lancer {

class Bvh8PacketAccel final : public PacketAccel<Bvh8Accel> {
  public:
    static constexpr int kPacketSize = kBvh8PacketSize;

    [[nodiscard]] std::string_view name() const override { return "bvh8_packet"; }
    // The rays per instruction of the packet's box and triangle tests, once built: 16 with the AVX-512
    // kernels, 8 with the AVX2 ones (BuildOptions::isa chooses), 1 in a build without AVX2, which traces
    // every ray through bvh8.
    [[nodiscard]] int lane_count() const;

  private:
    void build_structure(const Geometry& geometry, const BuildOptions& options) override;
    UpdateReport update_structure(const Geometry& geometry) override;
    [[nodiscard]] Bvh8PacketTarget target() const;
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;
    void intersect_packet_rays(const RayPacket& rays, HitPacket& hits,
                               TraversalCounters* counters) const override;

    const Bvh8PacketKernels* kernels_ = nullptr;
    float leaf_diagonal_ = 0.0f;  // mean_leaf_diagonal: the scale of Bvh8PacketTarget::coherent_width
    int streams_in_flight_ = 1;   // Bvh8PacketTarget::streams_in_flight
};

}  // namespace lancer
