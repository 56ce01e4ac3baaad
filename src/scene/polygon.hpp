// Triangulation of one planar polygon in 3D, as NFF `p` and `pp` give them: convex polygons become fans,
// concave ones (the 144-vertex gear faces of the SPD) are ear-clipped.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lancer/vec.hpp"

namespace lancer {

// The front normal, not normalised: cross(v1 - v0, v2 - v1) at the first corner (NFF's rule: the first
// three vertices make a convex corner), or Newell's normal of the whole outline when that corner is
// degenerate. Zero only when the polygon has no area.
[[nodiscard]] Vec3f polygon_normal(std::span<const Vec3f> polygon);

// Ear clipping costs O(n^2) ear tests of O(n) each on the worst outlines (a lap without an ear before each
// fallback clip): a non-convex polygon of more vertices is refused rather than left to run for hours. The
// largest concave face of the SPD is the gear's 144; a convex polygon of any size is a fan, in O(n).
inline constexpr std::size_t kMaxEarClippedVertices = 2048;

// Appends polygon.size() - 2 triangles to `triangles`, three indices into `polygon` each, with the
// polygon's winding (the front stays counter-clockwise). The polygon is projected on the plane of the
// dominant axis of its normal; if no vertex turns the wrong way there it becomes the fan (0, k, k + 1),
// otherwise ears are clipped. An outline that is not simple (self-intersecting, or all its points on a
// line) still gets polygon.size() - 2 triangles, some of them overlapping or flat. Returns false, appending
// nothing, for a non-convex outline of more than kMaxEarClippedVertices vertices.
[[nodiscard]] bool triangulate_polygon(std::span<const Vec3f> polygon, std::vector<std::uint32_t>& triangles);

}  // namespace lancer
