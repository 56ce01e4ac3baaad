#include "cuda/cwbvh_build.hpp"

#include <algorithm>
#include <cmath>
#include <span>
#include <stdexcept>
#include <string>

namespace lancer::gpu {
namespace {

// Indices are 32-bit and a primitive index becomes Hit::prim, an int32.
constexpr std::size_t kMaxEncodedCount = std::size_t{1} << 31;
constexpr std::uint32_t kNoWideNode = ~0u;

// bvh8's inner depth stays below BvhAccel::kMaxDepth (the binary tree's, which the collapse only shortens);
// splitting a leaf of up to BvhAccel::kMaxLeafSize triangles adds two levels (64 into 8 nodes of 8).
static_assert(kCwbvhStackSize >= BvhAccel::kMaxDepth + 2);
static_assert(BvhAccel::kMaxLeafSize <= kMaxLeafTriangles * kCwbvhWidth);

// A child of the node being encoded: a bvh8 inner node, a leaf, or a leaf split into a node of its own.
struct SourceChild {
    Box3f box;
    std::uint32_t wide_node = kNoWideNode;
    std::vector<std::uint32_t> prims;  // a leaf's, or a split leaf's, in bvh8's order
    bool inner = false;
};

// A node to encode at `index`: bvh8's node `wide_node`, or a split leaf (kNoWideNode) of `prims`.
struct PendingNode {
    std::uint32_t index = 0;
    std::uint32_t wide_node = kNoWideNode;
    std::vector<std::uint32_t> prims;
    int depth = 0;
};

Box3f triangle_bounds(const Triangle& triangle) {
    Box3f box;
    box.extend(triangle.v0);
    box.extend(triangle.v1);
    box.extend(triangle.v2);
    return box;
}

std::vector<SourceChild> children_of_wide_node(const WideBvhAccel<8>& bvh8, std::uint32_t index) {
    const WideBvhNode<8>& node = bvh8.nodes()[index];
    std::vector<SourceChild> children;
    for (int slot = 0; slot < 8; ++slot) {
        if (node.is_empty(slot)) continue;
        SourceChild child;
        child.box = node.child_bounds(slot);
        if (node.prim_count[slot] == 0) {
            child.wide_node = node.child[slot];
            child.inner = true;
        } else {
            const LeafSpan span = leaf_span<8>(node.child[slot], node.prim_count[slot]);
            for (std::uint32_t i = 0; i < node.prim_count[slot]; ++i)
                child.prims.push_back(bvh8.blocks()[span.first + i / 8].prim[i % 8]);
        }
        children.push_back(std::move(child));
    }
    return children;
}

// `prims` cut into `group_count` groups of nearly equal size by recursive median splits on the axis of
// largest centroid extent (a stable sort: the same groups every build).
void split_into_groups(const Geometry& geometry, std::vector<std::uint32_t> prims, std::size_t group_count,
                       std::vector<std::vector<std::uint32_t>>& groups) {
    if (group_count == 1) {
        groups.push_back(std::move(prims));
        return;
    }
    Box3f centroids;
    for (const std::uint32_t prim : prims)
        centroids.extend(triangle_bounds(geometry.triangles[prim]).center());
    const Vec3f extent = centroids.extent();
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    std::stable_sort(prims.begin(), prims.end(), [&](std::uint32_t a, std::uint32_t b) {
        return triangle_bounds(geometry.triangles[a]).center()[axis] <
               triangle_bounds(geometry.triangles[b]).center()[axis];
    });
    const std::size_t left_groups = group_count / 2;
    const auto left_size = static_cast<std::ptrdiff_t>(prims.size() * left_groups / group_count);
    split_into_groups(geometry, {prims.begin(), prims.begin() + left_size}, left_groups, groups);
    split_into_groups(geometry, {prims.begin() + left_size, prims.end()}, group_count - left_groups, groups);
}

// A split leaf's children: its triangles in up to 8 groups, each a leaf boxed by its triangles.
std::vector<SourceChild> children_of_split_leaf(const Geometry& geometry, std::vector<std::uint32_t> prims) {
    std::vector<std::vector<std::uint32_t>> groups;
    const std::size_t group_count = std::min<std::size_t>(kCwbvhWidth, prims.size());
    split_into_groups(geometry, std::move(prims), group_count, groups);
    std::vector<SourceChild> children;
    for (std::vector<std::uint32_t>& group : groups) {
        SourceChild child;
        for (const std::uint32_t prim : group)
            child.box.extend(triangle_bounds(geometry.triangles[prim]));
        child.prims = std::move(group);
        children.push_back(std::move(child));
    }
    return children;
}

// The leaf variant (cwbvh_layout.hpp): while a leaf holds more than kMaxLeafTriangles or the node's leaves
// more than kMaxNodeTriangles, the largest leaf (the first of equal ones) becomes an inner child. Returns
// how many did.
std::uint32_t fit_leaves_in_mask(std::vector<SourceChild>& children) {
    std::size_t leaf_triangles = 0;
    for (const SourceChild& child : children)
        leaf_triangles += child.inner ? 0 : child.prims.size();
    std::uint32_t split = 0;
    while (true) {
        SourceChild* largest = nullptr;
        for (SourceChild& child : children) {
            if (!child.inner && (largest == nullptr || child.prims.size() > largest->prims.size()))
                largest = &child;
        }
        if (largest == nullptr ||
            (largest->prims.size() <= kMaxLeafTriangles && leaf_triangles <= kMaxNodeTriangles))
            return split;
        largest->inner = true;
        leaf_triangles -= largest->prims.size();
        ++split;
    }
}

// The slot of each child for octant-ordered traversal (Ylitie et al. 2017, their child node ordering):
// slot s has bit (2 - axis) set for children on the + side of the parent's centre on that axis. The cost
// of child c in slot s is minus the projection of its centroid's offset on slot s's direction (+1 or -1 per
// axis); the cheapest free pair is taken first, greedily, ties to the first child and slot. The traversal
// visits slots in the order of slot ^ (the ray's octant ^ 7), highest first: nearest octant first.
std::array<int, kCwbvhWidth> assign_slots(const std::vector<SourceChild>& children, const Box3f& frame) {
    const Vec3f parent_center = frame.center();
    double cost[kCwbvhWidth][kCwbvhWidth];
    for (std::size_t c = 0; c < children.size(); ++c) {
        const Vec3f offset = children[c].box.center() - parent_center;
        for (int slot = 0; slot < kCwbvhWidth; ++slot) {
            double projection = 0.0;
            for (int axis = 0; axis < 3; ++axis)
                projection += ((slot >> (2 - axis)) & 1) != 0 ? offset[axis] : -offset[axis];
            cost[c][slot] = -projection;
        }
    }
    std::array<int, kCwbvhWidth> slot_of{};
    slot_of.fill(-1);
    bool slot_taken[kCwbvhWidth] = {};
    for (std::size_t assigned = 0; assigned < children.size(); ++assigned) {
        std::size_t best_child = 0;
        int best_slot = -1;
        for (std::size_t c = 0; c < children.size(); ++c) {
            if (slot_of[c] >= 0) continue;
            for (int slot = 0; slot < kCwbvhWidth; ++slot) {
                if (!slot_taken[slot] && (best_slot < 0 || cost[c][slot] < cost[best_child][best_slot]))
                    best_child = c, best_slot = slot;
            }
        }
        slot_of[best_child] = best_slot;
        slot_taken[best_slot] = true;
    }
    return slot_of;
}

// The smallest exponent whose 255 steps span `extent` in exact arithmetic, within the decodable range; the
// decode's rounding may still ask for the next one (quantize_axis).
int first_exponent(double extent) {
    if (!(extent > 0.0)) return kMinExponent;
    const double exponent = std::ceil(std::log2(extent / kQuantizationSteps));
    return static_cast<int>(std::clamp(exponent, double{kMinExponent}, double{kMaxExponent}));
}

// One axis of every child on the grid origin + q 2^exponent: lo rounded down and hi up in exact arithmetic,
// then moved by whole steps until the traversal's float decode contains the box (the rounding of the sum
// may cross the bound). False when a hi needs more than 255 steps: the caller takes a coarser grid. At
// kMaxExponent 255 steps decode to +inf, so some exponent succeeds.
bool quantize_axis(const std::array<Box3f, kCwbvhWidth>& boxes, int axis, float origin, int exponent,
                   CwbvhNode& node) {
    const float scale = quantization_scale(exponent);
    const double step = std::ldexp(1.0, exponent);
    const auto clamped = [](double q) {
        return static_cast<std::uint8_t>(std::clamp(q, 0.0, double{kQuantizationSteps}));
    };
    for (int slot = 0; slot < kCwbvhWidth; ++slot) {
        node.lo[axis][slot] = node.hi[axis][slot] = 0;
        if (boxes[slot].empty()) continue;
        const float lo = boxes[slot].lo[axis], hi = boxes[slot].hi[axis];
        std::uint8_t q_lo = clamped(std::floor((double{lo} - origin) / step));
        // q = 0 decodes to the origin exactly, the least lo.
        while (q_lo > 0 && decode_bound(origin, q_lo, scale) > lo)
            --q_lo;
        std::uint8_t q_hi = clamped(std::ceil((double{hi} - origin) / step));
        while (q_hi < kQuantizationSteps && decode_bound(origin, q_hi, scale) < hi)
            ++q_hi;
        if (decode_bound(origin, q_hi, scale) < hi) return false;
        node.lo[axis][slot] = q_lo;
        node.hi[axis][slot] = q_hi;
    }
    return true;
}

}  // namespace

void quantize_child_boxes(const std::array<Box3f, kCwbvhWidth>& boxes, CwbvhNode& node) {
    Box3f frame;
    for (const Box3f& box : boxes) {
        if (box.empty()) continue;
        if (!is_finite(box.lo) || !is_finite(box.hi))
            throw std::invalid_argument("cuda: a child box with a non-finite bound cannot be quantized");
        frame.extend(box);
    }
    for (int axis = 0; axis < 3; ++axis) {
        const float origin = frame.empty() ? 0.0f : frame.lo[axis];
        int exponent = frame.empty() ? 0 : first_exponent(double{frame.hi[axis]} - origin);
        while (!quantize_axis(boxes, axis, origin, exponent, node))
            ++exponent;
        node.origin[axis] = origin;
        node.exponent[axis] = static_cast<std::int8_t>(exponent);
    }
}

CompressedWideBvh compress_bvh8(const WideBvhAccel<8>& bvh8, const Geometry& geometry) {
    if (!geometry.spheres.empty())
        throw std::invalid_argument("cuda: the GPU kernels trace triangles only; the scene has spheres");
    CompressedWideBvh compressed;
    if (bvh8.nodes().empty()) return compressed;

    std::size_t references = 0;
    for (const WideBvhNode<8>& node : bvh8.nodes()) {
        for (int slot = 0; slot < 8; ++slot)
            references += node.prim_count[slot];
    }
    if (references >= kMaxEncodedCount || geometry.triangles.size() >= kMaxEncodedCount)
        throw std::invalid_argument(
            "cuda: 2^31 triangles or triangle references or more for the compressed BVH");
    compressed.triangles.reserve(references);

    compressed.nodes.resize(1);
    std::vector<PendingNode> pending;
    pending.push_back({0, 0, {}, 0});
    while (!pending.empty()) {
        PendingNode parent = std::move(pending.back());
        pending.pop_back();
        compressed.max_depth = std::max(compressed.max_depth, parent.depth);
        if (parent.depth > kCwbvhStackSize)
            throw std::invalid_argument("cuda: the compressed BVH is deeper than the traversal's stack (" +
                                        std::to_string(kCwbvhStackSize) + ")");
        std::vector<SourceChild> children = parent.wide_node != kNoWideNode
                                                ? children_of_wide_node(bvh8, parent.wide_node)
                                                : children_of_split_leaf(geometry, std::move(parent.prims));
        compressed.split_leaves += fit_leaves_in_mask(children);

        Box3f frame;
        for (const SourceChild& child : children)
            frame.extend(child.box);
        const std::array<int, kCwbvhWidth> slot_of = assign_slots(children, frame);
        std::array<int, kCwbvhWidth> child_in_slot{};
        child_in_slot.fill(-1);
        for (std::size_t c = 0; c < children.size(); ++c)
            child_in_slot[static_cast<std::size_t>(slot_of[c])] = static_cast<int>(c);

        CwbvhNode node{};
        node.child_base = static_cast<std::uint32_t>(compressed.nodes.size());
        node.triangle_base = static_cast<std::uint32_t>(compressed.triangles.size());
        std::array<Box3f, kCwbvhWidth> boxes;
        std::uint32_t next_child = node.child_base, next_triangle = 0;
        for (int slot = 0; slot < kCwbvhWidth; ++slot) {
            const int c = child_in_slot[static_cast<std::size_t>(slot)];
            node.meta[slot] = kEmptySlot;
            if (c < 0) continue;
            SourceChild& child = children[static_cast<std::size_t>(c)];
            boxes[static_cast<std::size_t>(slot)] = child.box;
            if (child.inner) {
                node.inner_mask = static_cast<std::uint8_t>(node.inner_mask | 1u << slot);
                node.meta[slot] = 0;
                pending.push_back({next_child++, child.wide_node, std::move(child.prims), parent.depth + 1});
                continue;
            }
            node.meta[slot] = leaf_meta(next_triangle, static_cast<std::uint32_t>(child.prims.size()));
            next_triangle += static_cast<std::uint32_t>(child.prims.size());
            for (const std::uint32_t prim : child.prims)
                compressed.triangles.push_back({geometry.triangles[prim], prim});
        }
        if (next_child >= kMaxEncodedCount)
            throw std::invalid_argument("cuda: 2^31 nodes or more for the compressed BVH");
        quantize_child_boxes(boxes, node);
        compressed.nodes.resize(next_child);
        compressed.nodes[parent.index] = node;
    }
    return compressed;
}

}  // namespace lancer::gpu
