// Whitted's ray tracer (Whitted 1980; Ferreira & Mendoza 2011, sections 4 and 5; the "Lancer de rayon"
// slides, "extension du modèle"), one tile at a time: every level of the ray tree of all the tile's camera
// samples is one batch of closest-hit rays through the SceneIntersector, and its shadow rays one batch of
// occlusion queries. docs/whitted.md.
#pragma once

#include <cstdint>

#include "lancer/camera.hpp"
#include "lancer/render.hpp"
#include "render/scene_intersector.hpp"

namespace lancer {

struct RayCounts {
    std::uint64_t primary = 0;
    std::uint64_t shadow = 0;
    std::uint64_t reflection = 0;  // total internal reflections included
    std::uint64_t refraction = 0;
};

class WhittedTracer {
  public:
    // The four must outlive the tracer; `options` is read for its Whitted fields (samples, depth, minimum
    // weight, Fresnel).
    WhittedTracer(const Scene& scene, const SceneIntersector& intersector, const PinholeCamera& camera,
                  const RenderOptions& options);

    // Renders the pixels [x0, x1) x [y0, y1) of `image` (linear RGB, the mean of each pixel's samples) and
    // returns the rays it traced. Each pixel depends on its own samples alone, added up in a fixed order.
    RayCounts render_tile(int x0, int y0, int x1, int y1, Image& image) const;

  private:
    const Scene& scene_;
    const SceneIntersector& intersector_;
    const PinholeCamera& camera_;
    const RenderOptions& options_;
};

}  // namespace lancer
