// Rays that run in the planes of an octree's cells: the NaN case of Revelles' parameters (0 * inf) for the
// octree walk, and the ties of the exit-face tests for the Plücker walk (docs/numerical-contract.md).
#pragma once

#include <cstdint>
#include <vector>

#include "accel/octree_build.hpp"
#include "lancer/ray.hpp"

namespace lancer::testing {

// `count` rays whose origins lie exactly on a plane of `octree`'s cells (a level from 0 to 6, one of its
// planes) with a zero direction component (+0 or -0) across it; every third lies in two planes at once,
// along an edge, and every fifth starts outside the root cube.
std::vector<Ray> cell_plane_rays(const Octree& octree, int count, std::uint32_t seed);

}  // namespace lancer::testing
