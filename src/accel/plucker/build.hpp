// The Plücker build's last step: an octree laid out as the connected word stream of layout.hpp (Portalez &
// Duguet 2016, section 3), and the octree recovered from a stream read back from a file.
#pragma once

#include "accel/octree_build.hpp"
#include "accel/plucker/layout.hpp"
#include "lancer/accel.hpp"

namespace lancer::plucker {

// Lays out a (balanced, unless options.balanced is false) octree: leaves in the build's cell order, or in
// Morton order (depth first) with options.morton; inner cells after the leaves in the unconstrained
// variant. Throws std::length_error when the stream would not fit 31-bit addresses.
[[nodiscard]] PluckerLayout layout_octree(const Geometry& geometry, const Octree& octree,
                                          const PluckerLayoutOptions& options);

// The tree the layout was made from: cells (levels, coordinates, children) from `locate`, leaf references
// from the stream. Throws std::invalid_argument naming the first inconsistency (a child index out of range
// or not after its parent, a cell with two parents, a level past kOctreeMaxLevel, a leaf address or a
// triangle range out of bounds).
[[nodiscard]] Octree recover_octree(const PluckerLayout& layout);

}  // namespace lancer::plucker
