// Comparing two structures' answers ray by ray: the oracle tests, and `lancer bench`, which checks every
// structure against the first one before it times them (validate while timing).
#pragma once

#include <cstddef>
#include <span>
#include <string>

#include "lancer/accel.hpp"

namespace lancer {

// Agreement: the same hit or miss, and t within 1e-5 relative. A different primitive at the same t is a
// tie, counted apart, not an error.
struct Agreement {
    std::size_t rays = 0, hits = 0, ties = 0, mismatches = 0;
    std::string first_mismatch;  // ray index, both answers

    [[nodiscard]] std::string summary() const;
};

[[nodiscard]] Agreement compare_hits(std::span<const Ray> rays, std::span<const Hit> expected,
                                     std::span<const Hit> actual);

// Occlusion must equal "the oracle found a hit".
[[nodiscard]] Agreement compare_occlusion(std::span<const Ray> rays, std::span<const Hit> expected,
                                          std::span<const std::uint8_t> occluded);

}  // namespace lancer
