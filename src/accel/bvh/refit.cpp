#include "accel/bvh/refit.hpp"

#include <algorithm>
#include <array>
#include <limits>

#include "accel/build_util.hpp"
#include "accel/bvh/build.hpp"
#include "accel/simd_float.hpp"
#include "core/host_device.hpp"
#include "core/parallel.hpp"

namespace lancer {
namespace {

// A refitted subtree: its box, the sum of the SAH terms of its nodes before the division by the root's
// area, and its primitive references.
struct Refitted {
    Box3f box;
    double weighted_area = 0.0;
    std::size_t references = 0;
};

// Subtrees of at least this many nodes refit their two children as two tasks: below it a task would cost
// about as much as the nodes it refits.
constexpr std::uint32_t kParallelNodes = 2048;
// A subtree of at most this many nodes asks for all its triangles before it refits them: the leaves hold
// triangles from anywhere in the array, and fetching one at a time left the refit waiting on memory.
constexpr std::uint32_t kPrefetchNodes = 32;

// Asks for the lines of a primitive's triangle (36 bytes, which may straddle two lines).
void prefetch_primitive(const Geometry& geometry, std::uint32_t prim) {
    if (prim >= geometry.triangles.size()) return;
    const Triangle* triangle = &geometry.triangles[prim];
    prefetch_line(triangle);
    prefetch_line(reinterpret_cast<const char*>(triangle + 1) - 1);
}

// A node's box as the builders store it: the tight box of what it holds grown by the scene's geometric
// tolerance (build.cpp, "compact"; docs/numerical-contract.md, "Boxes"). The empty box stays empty.
Box3f grown(const Box3f& tight, const Vec3f& margin) {
    return {tight.lo - margin, tight.hi + margin};
}

// A binary BVH's leaves as the refit reads them: the primitives of a Geometry...
struct GeometryLeaves {
    const Geometry& geometry;

    [[nodiscard]] Box3f box(std::uint32_t prim) const { return primitive_bounds(geometry, prim); }
    void prefetch(std::uint32_t prim) const { prefetch_primitive(geometry, prim); }
};

// ... or boxes given as they are (a two-level scene's instances), contiguous, so nothing worth prefetching.
struct BoxLeaves {
    std::span<const Box3f> boxes;

    [[nodiscard]] Box3f box(std::uint32_t prim) const { return boxes[prim]; }
    void prefetch(std::uint32_t /*prim*/) const {}
};

template <class Leaves>
struct BinaryRefit {
    Leaves leaves;
    std::span<const std::uint32_t> prim_indices;
    HugePageVector<BvhNode>& nodes;
    Vec3f margin;

    // The subtree of node `index`, which ends before node `end` (depth first: a node, its first subtree, its
    // second). `prefetched`: an enclosing subtree has asked for its triangles already.
    Refitted subtree(std::uint32_t index, std::uint32_t end, bool prefetched = false) const {
        if (!prefetched && end - index <= kPrefetchNodes) {
            for (std::uint32_t n = index; n < end; ++n) {
                for (std::uint32_t i = nodes[n].offset; i < nodes[n].offset + nodes[n].prim_count; ++i)
                    leaves.prefetch(prim_indices[i]);
            }
            prefetched = true;
        }
        BvhNode& node = nodes[index];
        Refitted refitted;
        if (node.is_leaf()) {
            Box3f tight;
            for (std::uint32_t i = node.offset; i < node.offset + node.prim_count; ++i)
                tight.extend(leaves.box(prim_indices[i]));
            refitted.box = grown(tight, margin);
            refitted.weighted_area =
                static_cast<double>(refitted.box.surface_area()) * node.prim_count * kSahPrimitiveCost;
            refitted.references = node.prim_count;
        } else {
            const std::uint32_t second = node.offset;
            Refitted first_child, second_child;
            auto refit_first = [&] { first_child = subtree(index + 1, second, prefetched); };
            auto refit_second = [&] { second_child = subtree(second, end, prefetched); };
            if (end - index >= kParallelNodes) {
                parallel::invoke(refit_first, refit_second);
            } else {
                refit_first(), refit_second();
            }
            // The union of grown boxes is the grown union: lo - margin rounds monotonically in lo.
            refitted.box = first_child.box;
            refitted.box.extend(second_child.box);
            refitted.weighted_area = static_cast<double>(refitted.box.surface_area()) * kSahNodeCost +
                                     first_child.weighted_area + second_child.weighted_area;
            refitted.references = first_child.references + second_child.references;
        }
        node.lo = refitted.box.lo;
        node.hi = refitted.box.hi;
        return refitted;
    }
};

// The SAH cost of a refitted tree; a tree whose root has no area costs its primitive references.
double normalised_cost(const Refitted& root) {
    const double root_area = root.box.surface_area();
    return root_area > 0.0 ? root.weighted_area / root_area : static_cast<double>(root.references);
}

// A block's lanes rewritten from the moved triangles, as the build writes them (write_block_lane); returns
// the tight box of its primitives.
template <int W>
Box3f rewrite_block(const Geometry& geometry, TriangleBlock<W>& block) {
    Box3f box;
    for (int lane = 0; lane < W; ++lane) {
        const std::uint32_t prim = block.prim[lane];
        write_block_lane(geometry, prim, lane, block);
        if (prim != TriangleBlock<W>::kNoPrimitive) box.extend(primitive_bounds(geometry, prim));
    }
    return box;
}

#if defined(__AVX2__)
// Eight lanes at once: the first eight floats of each triangle (v0, v1, v2.x, v2.y; the block's fields are
// the Triangle's floats in order) transposed in registers, v2.z set lane by lane, the box taken from the
// registers. A block written lane by lane and read back as vectors waited on its scalar stores.
template <>
Box3f rewrite_block<8>(const Geometry& geometry, TriangleBlock<8>& block) {
    using Ops = simd::Avx2;
    static_assert(sizeof(Triangle) == 9 * sizeof(float) && sizeof(block.vertex) == 9 * 8 * sizeof(float));
    const float nan = std::numeric_limits<float>::quiet_NaN();
    Ops::Float rows[8];
    std::array<float, 8> last;  // v2.z of each lane
    Box3f box;
    for (int lane = 0; lane < 8; ++lane) {
        const std::uint32_t prim = block.prim[lane];
        if (prim < geometry.triangles.size()) {
            const Triangle& triangle = geometry.triangles[prim];
            rows[lane] = _mm256_loadu_ps(&triangle.v0.x);
            last[static_cast<std::size_t>(lane)] = triangle.v2.z;
        } else {
            rows[lane] = Ops::broadcast(nan);
            last[static_cast<std::size_t>(lane)] = nan;
            if (prim != TriangleBlock<8>::kNoPrimitive) box.extend(primitive_bounds(geometry, prim));
        }
    }
    Ops::Float fields[8];
    Ops::transpose8(rows, fields);
    const Ops::Float v2z =
        _mm256_setr_ps(last[0], last[1], last[2], last[3], last[4], last[5], last[6], last[7]);
    auto field = [&](int f) { return f < 8 ? fields[f] : v2z; };
    float* out = &block.vertex[0][0][0];
    for (int f = 0; f < 9; ++f)
        Ops::store(out + 8 * f, field(f));
    // minps(x, y) is y where x is NaN: lanes without a triangle drop out.
    for (int axis = 0; axis < 3; ++axis) {
        Ops::Float lo = Ops::broadcast(kInfinity), hi = Ops::broadcast(-kInfinity);
        for (int v = 0; v < 3; ++v) {
            lo = Ops::min(field(3 * v + axis), lo);
            hi = Ops::max(field(3 * v + axis), hi);
        }
        box.lo[axis] = std::min(box.lo[axis], Ops::reduce_min(lo));
        box.hi[axis] = std::max(box.hi[axis], Ops::reduce_max(hi));
    }
    return box;
}
#endif

template <int W>
struct WideRefit {
    const Geometry& geometry;
    HugePageVector<WideBvhNode<W>>& nodes;
    HugePageVector<TriangleBlock<W>>& blocks;
    Vec3f margin;

    // Nodes of these first levels refit their children as tasks: W at the root, W^2 below it, enough to
    // balance any core count lancer runs on; deeper, a subtree is too small to be worth a task.
    static constexpr int kParallelLevels = 2;

    // A leaf child's blocks, rewritten from the geometry, and its header's block boxes (has_leaf_boxes);
    // returns their primitives' box, grown.
    Box3f leaf(std::uint32_t child, std::uint32_t prim_count) const {
        Box3f box;
        const LeafSpan span = leaf_span<W>(child, prim_count);
        for (std::uint32_t b = span.first; b < span.end; ++b)
            box.extend(rewrite_block(geometry, blocks[b]));
        if constexpr (kLeafBoxes<W>) {
            if (has_leaf_boxes(child)) {
                write_leaf_boxes(geometry, &blocks[span.first], span.end - span.first, margin.x,
                                 blocks[leaf_start(child)]);
            }
        }
        return grown(box, margin);
    }

    Refitted node(std::uint32_t index, int level) const {
        WideBvhNode<W>& wide = nodes[index];
        // The triangles of every leaf child asked for at once, before any is read: they lie anywhere in the
        // array, and fetching them one at a time left the refit waiting on memory.
        for (int slot = 0; slot < W; ++slot) {
            const LeafSpan span = leaf_span<W>(wide.child[slot], wide.prim_count[slot]);
            for (std::uint32_t b = span.first; wide.prim_count[slot] > 0 && b < span.end; ++b) {
                for (int lane = 0; lane < W; ++lane)
                    prefetch_primitive(geometry, blocks[b].prim[lane]);
            }
        }
        std::array<Refitted, W> children;
        auto refit_child = [&](std::size_t slot) {
            if (wide.prim_count[slot] > 0) {
                children[slot].box = leaf(wide.child[slot], wide.prim_count[slot]);
                children[slot].weighted_area = static_cast<double>(children[slot].box.surface_area()) *
                                               wide.prim_count[slot] * kSahPrimitiveCost;
                children[slot].references = wide.prim_count[slot];
            } else if (wide.child[slot] != 0) {  // node 0 is the root, never a child: 0 marks an empty slot
                children[slot] = node(wide.child[slot], level + 1);
            }
        };
        if (level < kParallelLevels) {
            parallel::for_each_index(0, W, refit_child);
        } else {
            for (std::size_t slot = 0; slot < W; ++slot)
                refit_child(slot);
        }
        Refitted refitted;
        for (int slot = 0; slot < W; ++slot) {
            // An empty slot keeps its inverted box, and so does a leaf of spheres that cannot be hit.
            const Box3f& box = children[static_cast<std::size_t>(slot)].box;
            for (int axis = 0; axis < 3; ++axis) {
                wide.bounds[WideBvhNode<W>::kLo][axis][slot] = box.lo[axis];
                wide.bounds[WideBvhNode<W>::kHi][axis][slot] = box.hi[axis];
            }
            refitted.box.extend(box);
            refitted.weighted_area += children[static_cast<std::size_t>(slot)].weighted_area;
            refitted.references += children[static_cast<std::size_t>(slot)].references;
        }
        refitted.weighted_area += static_cast<double>(refitted.box.surface_area()) * kSahNodeCost;
        return refitted;
    }
};

}  // namespace

float refit_margin(const Geometry& geometry, const Box3f& hit_bounds) {
    // The builders grow by the tolerance of their root's tight box, the union of every primitive's box: the
    // box of what can be hit, and the spheres that cannot.
    Box3f tree_box = hit_bounds;
    for (const Sphere& sphere : geometry.spheres) {
        if (!(sphere.radius > 0.0f)) tree_box.extend(sphere.bounds());
    }
    return geometric_tolerance(tree_box);
}

double refit_bvh(const Geometry& geometry, std::span<const std::uint32_t> prim_indices,
                 HugePageVector<BvhNode>& nodes, float margin) {
    if (nodes.empty()) return 0.0;
    return normalised_cost(
        BinaryRefit<GeometryLeaves>{{geometry}, prim_indices, nodes, Vec3f(margin)}.subtree(
            0, static_cast<std::uint32_t>(nodes.size())));
}

double refit_bvh_over_boxes(std::span<const Box3f> boxes, std::span<const std::uint32_t> prim_indices,
                            HugePageVector<BvhNode>& nodes) {
    if (nodes.empty()) return 0.0;
    // The builder's margin: the tolerance of the root's tight box (NodeSlots::compact).
    Box3f root;
    for (const std::uint32_t id : prim_indices)
        root.extend(boxes[id]);
    return normalised_cost(
        BinaryRefit<BoxLeaves>{{boxes}, prim_indices, nodes, Vec3f(geometric_tolerance(root))}.subtree(
            0, static_cast<std::uint32_t>(nodes.size())));
}

template <int W>
double refit_wide_bvh(const Geometry& geometry, HugePageVector<WideBvhNode<W>>& nodes,
                      HugePageVector<TriangleBlock<W>>& blocks, float margin) {
    if (nodes.empty()) return 0.0;
    return normalised_cost(WideRefit<W>{geometry, nodes, blocks, Vec3f(margin)}.node(0, 0));
}

template <int W>
double wide_bvh_sah_cost(std::span<const WideBvhNode<W>> nodes) {
    if (nodes.empty()) return 0.0;
    double weighted_area = 0.0;
    std::size_t references = 0;
    Box3f root_box;
    for (std::size_t index = 0; index < nodes.size(); ++index) {
        const WideBvhNode<W>& node = nodes[index];
        Box3f node_box;
        for (int slot = 0; slot < W; ++slot) {
            if (node.is_empty(slot)) continue;
            node_box.extend(node.child_bounds(slot));
            references += node.prim_count[slot];
            weighted_area += static_cast<double>(node.child_bounds(slot).surface_area()) *
                             node.prim_count[slot] * kSahPrimitiveCost;
        }
        weighted_area += static_cast<double>(node_box.surface_area()) * kSahNodeCost;
        if (index == 0) root_box = node_box;
    }
    const double root_area = root_box.surface_area();
    return root_area > 0.0 ? weighted_area / root_area : static_cast<double>(references);
}

template double refit_wide_bvh<4>(const Geometry&, HugePageVector<WideBvhNode<4>>&,
                                  HugePageVector<TriangleBlock<4>>&, float);
template double refit_wide_bvh<8>(const Geometry&, HugePageVector<WideBvhNode<8>>&,
                                  HugePageVector<TriangleBlock<8>>&, float);
template double wide_bvh_sah_cost<4>(std::span<const WideBvhNode<4>>);
template double wide_bvh_sah_cost<8>(std::span<const WideBvhNode<8>>);

}  // namespace lancer
