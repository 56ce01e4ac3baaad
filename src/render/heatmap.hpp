// Traversal-cost pictures (the paper's Figure 6): per-pixel counts mapped through a colour ramp, with a
// legend so that two pictures can be read against each other.
#pragma once

#include <cstdint>
#include <span>

#include "lancer/render.hpp"

namespace lancer {

// An inferno-like ramp from black (0) through purple, red and orange to pale yellow (1); clamped.
[[nodiscard]] Vec3f heat_color(float fraction);

// Fills `image` from one count per pixel, scaled by the image's maximum count, then draws the legend:
// a ramp bar in the bottom-left corner labelled with 0 and that maximum.
void heat_to_image(std::span<const std::uint32_t> counts, Image& image);

}  // namespace lancer
