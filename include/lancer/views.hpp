// The secondary benchmark views of shared/bench/VIEWS.md: incoherent rays made from the canonical view's
// hits, the work of a path tracer's bounce (diffuse) and of a renderer's shadow rays (shadow).
#pragma once

#include <span>
#include <string_view>
#include <vector>

#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer {

enum class SecondaryView {
    Diffuse,  // 4 cosine-weighted rays about the normal per hit; closest hit wanted
    Shadow,   // 1 ray per hit to the point light, tfar = 1 - 1e-4; any hit wanted
};

[[nodiscard]] std::string_view secondary_view_name(SecondaryView view);

// The rays of `view`, in pixel order (a pixel's 4 diffuse rays together), from the closest hits `hits` of
// the canonical view's rays `primary` (one per pixel, in pixel order) on `geometry`, whose box places the
// light and sizes the origin offset. A sphere hit takes the sphere's normal. Pixels that miss give none.
[[nodiscard]] std::vector<Ray> secondary_view_rays(SecondaryView view, const Geometry& geometry,
                                                   std::span<const Ray> primary, std::span<const Hit> hits);

}  // namespace lancer
