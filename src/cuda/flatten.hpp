// The host side of the GPU path, plain C++ (g++): the CPU BVH flattened into Aila-Laine nodes, the Plücker
// octree's arrays viewed as they are, the constant tables and the camera frame. Every function refuses what
// the GPU kernels do not trace, with a message that says what (std::invalid_argument).
#pragma once

#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/plucker/walk.hpp"
#include "cuda/gpu_layout.hpp"
#include "lancer/scene.hpp"

namespace lancer::gpu {

struct FlatBvh {
    std::vector<AilaLaineNode> nodes;
    std::vector<TriangleRef> triangles;  // in leaf order (BvhAccel::prim_indices)

    [[nodiscard]] BvhView view() const {
        return {nodes.data(), static_cast<std::uint32_t>(nodes.size()), triangles.data()};
    }
};

// The inner nodes of `bvh` (built on `geometry`) in the same depth-first order, each with both children's
// boxes; a root that is a leaf gets an inner node of its own whose second child's box (+inf, +inf) no
// ray enters. Throws for spheres (the GPU traces triangles) and for more than kMaxTriangleReferences.
[[nodiscard]] FlatBvh flatten_bvh(const BvhAccel& bvh, const Geometry& geometry);

// The octree's arrays as the CPU walks them (plucker::view_of). Throws unless the layout holds triangles
// only.
[[nodiscard]] plucker::PluckerView plucker_view(const plucker::PluckerLayout& layout);

}  // namespace lancer::gpu
