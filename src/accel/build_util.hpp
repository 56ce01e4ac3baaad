// Geometry helpers every spatial build shares: primitive bounds, conservative primitive-box overlap (which
// cells or nodes must reference a primitive) and the box of a primitive clipped to a box ("perfect splits",
// Havran 2000; Wald & Havran 2006 section 4.2).
#pragma once

#include <cstdint>
#include <vector>

#include "lancer/box.hpp"
#include "lancer/scene.hpp"

namespace lancer {

// Inline: the refits call it for every primitive of every frame.
[[nodiscard]] inline Box3f primitive_bounds(const Geometry& geometry, std::uint32_t prim) {
    if (prim < geometry.triangles.size()) return geometry.triangles[prim].bounds();
    return geometry.spheres[prim - geometry.triangles.size()].bounds();
}

// The box grown by a relative margin of its own size (plus an absolute one for flat boxes), so that
// rounding in an overlap or clipping test never drops a primitive that touches the box: an extra
// reference costs a test, a missing one costs a wrong answer.
[[nodiscard]] Box3f grown_for_overlap(const Box3f& box);

// Whether the primitive may intersect the closed box (triangles: the separating-axis test of
// Akenine-Moller 2001 against the grown box; spheres: centre-to-box distance against the radius).
[[nodiscard]] bool primitive_overlaps_box(const Geometry& geometry, std::uint32_t prim, const Box3f& box);

// Bounds of the part of the primitive inside the box (triangles: Sutherland-Hodgman clipping against the
// six planes of the grown box, then intersected with the box; spheres: their bounds intersected with the
// box). Empty when the primitive misses the box.
[[nodiscard]] Box3f clipped_primitive_bounds(const Geometry& geometry, std::uint32_t prim, const Box3f& box);

// Structures treat their node boxes and cells as grown by this distance, so that no structure culls a hit
// the kernel reports and brute force finds (docs/numerical-contract.md, "Boxes"): 2^-20 (8 ulps) of the
// scene's largest coordinate, for the rounding of coordinates, plus 2^-19 of its largest side
// (kKernelTolerance, core/ray_conditioning.hpp), for the triangle tests' rounding, a few 2^-24 |T| from an
// origin that ray conditioning keeps within 4.5 sides of every vertex.
[[nodiscard]] float geometric_tolerance(const Box3f& scene_bounds);

// The box of the primitives that can be hit: the triangles and the spheres of radius > 0.
[[nodiscard]] Box3f hit_bounds(const Geometry& geometry);

// `geometry` scaled by 2^exponent into `triangles` and `spheres`, resized to its counts (their storage kept
// when the counts are), and the box of its primitives that can be hit: the copy Accel::built_geometry holds
// for a scene whose size lies outside the ordinary range (scene_scale_exponent, core/ray_conditioning.hpp),
// exact but for coordinates that underflow far below the scene's rounding.
Box3f scale_geometry(const Geometry& geometry, int exponent, std::vector<Triangle>& triangles,
                     std::vector<Sphere>& spheres);

[[nodiscard]] inline Box3f intersection(const Box3f& a, const Box3f& b) {
    return {max(a.lo, b.lo), min(a.hi, b.hi)};
}

}  // namespace lancer
