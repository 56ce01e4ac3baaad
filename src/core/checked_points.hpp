// The check every structure build and every update makes of its input: the box of a point array and the first
// item with a coordinate NaN or outside the coordinate domain (lancer/scene.hpp, kCoordinateLimit).
#pragma once

#include <cstddef>
#include <span>

#include "lancer/scene.hpp"

namespace lancer {

struct CheckedPoints {
    static constexpr std::size_t kNone = static_cast<std::size_t>(-1);
    Box3f box;  // NaN coordinates drop out of it
    std::size_t first_outside = kNone;
};

// `coordinates`: points as xyz triples, grouped in items of `points_per_item` consecutive points (a
// triangle's three corners, or one vertex); first_outside numbers items. In parallel and vectorised: an
// animation checks every vertex of every frame. The box and the least index are exact whatever the chunks.
[[nodiscard]] CheckedPoints check_points(std::span<const float> coordinates, std::size_t points_per_item);

}  // namespace lancer
