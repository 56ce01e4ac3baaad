// The children of one wide node in the greedy collapse of a binary BVH (Dammertz, Hanika & Keller, "Shallow
// Bounding Volume Hierarchies for Fast SIMD Ray Tracing of Incoherent Rays", EGSR 2008, section 3): shared by
// the wide BVHs (bvh_wide.cpp) and the two-level scenes' top level (instance/instanced_scene.cpp).
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "accel/bvh/bvh.hpp"

namespace lancer {

// The binary subtrees that become the children of the wide node rooted at `binary_root` (an inner node, or
// a leaf when the whole tree is one), in the binary left-to-right order; returns their count. The node starts
// with the root's two children and repeatedly opens the inner child of largest surface area (the one a ray
// is most likely to enter; the first of equal areas) until it has W children or only leaves are left.
// `is_leaf(i)`: whether binary node i stays whole as a wide leaf.
template <int W, class IsLeaf>
int collapse_children(const HugePageVector<BvhNode>& binary, std::uint32_t binary_root, IsLeaf&& is_leaf,
                      std::array<std::uint32_t, W>& children) {
    int count = 0;
    if (is_leaf(binary_root)) {
        children[count++] = binary_root;
    } else {
        children[count++] = binary_root + 1;
        children[count++] = binary[binary_root].offset;
    }
    while (count < W) {
        int widest = -1;
        float widest_area = -1.0f;
        for (int i = 0; i < count; ++i) {
            const float area = binary[children[i]].bounds().surface_area();
            if (!is_leaf(children[i]) && area > widest_area) widest = i, widest_area = area;
        }
        if (widest < 0) break;
        const std::uint32_t opened = children[widest];
        std::copy_backward(children.begin() + widest + 1, children.begin() + count,
                           children.begin() + count + 1);
        children[widest] = opened + 1;
        children[widest + 1] = binary[opened].offset;
        ++count;
    }
    return count;
}

}  // namespace lancer
