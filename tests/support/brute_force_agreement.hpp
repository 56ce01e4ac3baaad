// The check a structure's own tests end with: it answers as the brute-force oracle does, closest hit and
// occlusion, on every ray (STYLE.md, habit 5).
#pragma once

#include <cstddef>
#include <span>

#include "lancer/accel.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer::testing {

// `accel`, built on `geometry` with `test`, gives brute force's closest hits and occlusion on every ray, and
// finds at least `min_hits` hits, so that the rays do meet the scene; a GoogleTest failure otherwise.
void expect_brute_force_answers(const Accel& accel, const Geometry& geometry, TriangleTest test,
                                std::span<const Ray> rays, std::size_t min_hits);

}  // namespace lancer::testing
