// The query contract every structure keeps on any ray (docs/numerical-contract.md), checked against brute
// force for the rays and plo harnesses: a disagreement or an unclean answer is a finding (abort).
#pragma once

#include <span>
#include <vector>

#include "lancer/accel.hpp"

namespace lancer::fuzz {

// Brute force's closest hits: the oracle. Checks that they are clean themselves (see check_clean).
[[nodiscard]] std::vector<Hit> oracle_hits(const Geometry& geometry, TriangleTest test,
                                           std::span<const Ray> rays);
// The same from a brute-force structure already built on `geometry`.
[[nodiscard]] std::vector<Hit> oracle_hits(const Accel& brute, std::span<const Ray> rays,
                                           const Geometry& geometry);

// Closest hits and occlusion of `accel` (built on `geometry`) agree with the oracle (compare_hits,
// compare_occlusion: 0 mismatches) and are clean.
void check_agrees_with_oracle(const Accel& accel, std::span<const Ray> rays, std::span<const Hit> oracle,
                              const Geometry& geometry);

// Answers of a structure with its own kernels (Embree), which agree with ours only within a tolerance
// (tests/accel/embree_test.cpp): clean, and invalid rays miss.
void check_clean_answers(const Accel& accel, std::span<const Ray> rays, const Geometry& geometry);

}  // namespace lancer::fuzz
