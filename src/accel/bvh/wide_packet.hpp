// Large-packet traversal of the 8-wide BVH (lancer issue 20): 64 consecutive rays (one 8x8 tile of
// primary rays) walk `bvh8` together. Each node culls its 8 children for the whole packet at once with
// interval arithmetic on the packet's origins and reciprocal directions (Overbeck, Ramamoorthi & Mark,
// "Large Ray Packets for Real-time Whitted Ray Tracing", RT 2008; Fuetterling et al., "Efficient Ray Tracing
// Kernels for Modern CPU Architectures", JCGT 2015); a child that survives is tested against the packet's
// active rays, 8 or 16 per instruction, when it is visited; and a leaf tests each triangle against the
// active rays with the same lane kernels as bvh8's triangle blocks (triangle_block.hpp), so every ray gets
// bvh8's hit, bit for bit. A packet whose rays disagree on a direction sign, or has a direction component
// whose reciprocal is not finite, goes through bvh8 one ray at a time. docs/accel/packets.md has the
// design note and the measurements.
#pragma once

#include <cstdint>

#include "accel/bvh/wide.hpp"
#include "lancer/accel.hpp"

namespace lancer {

class WidePacketAccel final : public Accel {
  public:
    // Rays traced together: one 8x8 tile of `lancer bench`, and the 64 bits of a lane mask.
    static constexpr int kPacketSize = 64;
    static_assert(kPacketSize == RayPacket::kMaxSize, "a RayPacket is traced as one packet");

    // The rays per instruction of the packet's box and triangle tests: 16 (AVX-512) where the build targets
    // it, else 8 (AVX2); 1 in a build without AVX2, which traces every ray through bvh8. Where the widest is
    // 16, 8 may be asked for, so that the tests cover both kernels; any other count throws
    // std::invalid_argument.
    static int widest_lane_count();
    explicit WidePacketAccel(int lane_count = widest_lane_count());

    [[nodiscard]] std::string_view name() const override { return "bvh8_packet"; }
    [[nodiscard]] int lane_count() const { return lane_count_; }
    // The build of `bvh8`, untouched.
    [[nodiscard]] AccelStats stats() const override { return bvh8_.stats(); }
    [[nodiscard]] std::size_t memory_bytes() const override { return bvh8_.memory_bytes(); }

  private:
    void build_structure(const Geometry& geometry, const BuildOptions& options) override;
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;
    void intersect_packet_rays(const RayPacket& rays, HitPacket& hits,
                               TraversalCounters* counters) const override;

    Bvh8Accel bvh8_;
    Geometry geometry_;
    TriangleTest triangle_test_ = TriangleTest::MollerTrumbore;
    int lane_count_;
};

}  // namespace lancer
