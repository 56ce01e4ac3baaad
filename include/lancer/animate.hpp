// The deformation that `lancer bench --animate` and `lancer render --animate` apply to a scene's meshes: a
// deterministic stand-in for a physics step or a skinned character, so that refits and rebuilds are timed on
// the same frames everywhere (docs/accel/refit.md, "The animated benchmark").
#pragma once

#include <span>
#include <vector>

#include "lancer/box.hpp"
#include "lancer/scene.hpp"
#include "lancer/vec.hpp"

namespace lancer {

// A sine wave travelling along x through `bounds` that lifts each vertex along y:
//   y += A sin(2 pi (x - lo.x) / extent.x - 2 pi frame / frame_count),  A = amplitude * largest extent,
// one wavelength across the box, one period over the frames. Frame `frame_count` is frame 0 again.
struct SineWave {
    Box3f bounds;             // the rest pose's box, which the wave is laid over
    int frame_count = 1;      // frames per period, at least 1
    float amplitude = 0.05f;  // of the box's largest extent

    // `rest` moved to frame `frame` in `out` (the same size). Computed in double, rounded once per
    // coordinate: the same positions on every machine with the same libm.
    void apply(std::span<const Vec3f> rest, int frame, std::span<Vec3f> out) const;
};

// The rest positions of every mesh of `scene`, moved to frame `frame` of `wave`: one array per mesh.
[[nodiscard]] std::vector<std::vector<Vec3f>> deformed_meshes(const Scene& scene, const SineWave& wave,
                                                              int frame);

}  // namespace lancer
