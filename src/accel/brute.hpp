// The oracle: every ray against every primitive. Every other structure is tested against it.
#pragma once

#include "lancer/accel.hpp"

namespace lancer {

class BruteAccel final : public Accel {
  public:
    [[nodiscard]] std::string_view name() const override { return "brute"; }
    [[nodiscard]] AccelStats stats() const override;
    [[nodiscard]] std::size_t memory_bytes() const override { return 0; }

  private:
    void build_structure(const Geometry& geometry, const BuildOptions& options) override;
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;

    Geometry geometry_;
    BuildOptions options_;
};

}  // namespace lancer
