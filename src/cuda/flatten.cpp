#include "cuda/flatten.hpp"

#include <stdexcept>
#include <string>

namespace lancer::gpu {
namespace {

void set_child_box(AilaLaineNode& node, int child, const Box3f& box) {
    if (child == 0) {
        node.c0_lo_x = box.lo.x, node.c0_hi_x = box.hi.x, node.c0_lo_y = box.lo.y, node.c0_hi_y = box.hi.y;
        node.c0_lo_z = box.lo.z, node.c0_hi_z = box.hi.z;
    } else {
        node.c1_lo_x = box.lo.x, node.c1_hi_x = box.hi.x, node.c1_lo_y = box.lo.y, node.c1_hi_y = box.hi.y;
        node.c1_lo_z = box.lo.z, node.c1_hi_z = box.hi.z;
    }
}

}  // namespace

FlatBvh flatten_bvh(const BvhAccel& bvh, const Geometry& geometry) {
    if (!geometry.spheres.empty())
        throw std::invalid_argument("cuda: the GPU kernels trace triangles only; the scene has spheres");
    const HugePageVector<BvhNode>& nodes = bvh.nodes();
    const auto& prim_indices = bvh.prim_indices();
    if (prim_indices.size() >= kMaxTriangleReferences)
        throw std::invalid_argument("cuda: more than 2^25 triangle references for the GPU BVH");
    FlatBvh flat;
    flat.triangles.reserve(prim_indices.size());
    for (const std::uint32_t prim : prim_indices)
        flat.triangles.push_back({geometry.triangles[prim], prim});
    if (nodes.empty()) return flat;

    // Inner node index on the GPU of each CPU node (depth-first order kept, leaves dropped).
    std::vector<std::int32_t> gpu_index(nodes.size(), -1);
    std::int32_t inner = 0;
    for (std::size_t i = 0; i < nodes.size(); ++i)
        if (!nodes[i].is_leaf()) gpu_index[i] = inner++;
    const auto child_word = [&](std::uint32_t child) {
        const BvhNode& node = nodes[child];
        return node.is_leaf() ? leaf_word(node.offset, node.prim_count) : gpu_index[child];
    };
    if (nodes[0].is_leaf()) {
        AilaLaineNode root{};
        set_child_box(root, 0, nodes[0].bounds());
        set_child_box(root, 1, {Vec3f(kInfinity), Vec3f(kInfinity)});
        root.child[0] = root.child[1] = child_word(0);
        flat.nodes.push_back(root);
        return flat;
    }
    flat.nodes.resize(static_cast<std::size_t>(inner));
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        if (nodes[i].is_leaf()) continue;
        AilaLaineNode& node = flat.nodes[static_cast<std::size_t>(gpu_index[i])];
        node = {};
        const std::uint32_t children[2] = {static_cast<std::uint32_t>(i + 1), nodes[i].offset};
        for (int c = 0; c < 2; ++c) {
            set_child_box(node, c, nodes[children[c]].bounds());
            node.child[c] = child_word(children[c]);
        }
    }
    return flat;
}

plucker::PluckerView plucker_view(const plucker::PluckerLayout& layout) {
    for (const plucker::PluckerPrimitive& primitive : layout.primitives)
        if (primitive.prim >= layout.triangle_count)
            throw std::invalid_argument("cuda: the GPU kernels trace triangles only; the scene has spheres");
    return plucker::view_of(layout);
}

}  // namespace lancer::gpu
