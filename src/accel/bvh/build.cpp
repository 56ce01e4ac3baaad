#include "accel/bvh/build.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>
#include <tuple>

#include "accel/build_util.hpp"
#include "core/parallel.hpp"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace lancer {
namespace {

// The SAH of seed 002: T(child) = T_box + A(child) / A(node) N(child) T_object, with T_box = T_object = 1.
// Past this depth every split is an object median, so the depth stays below kMaxDepth for any input:
// 64 + log2(2^32) <= 96.
constexpr int kMedianSplitDepth = 64;
static_assert(kMedianSplitDepth + 32 <= BvhAccel::kMaxDepth);

struct BuildRef {
    Box3f bounds;
    Vec3f centroid;
    std::uint32_t prim = 0;
};

// Centroid order on one axis, ties by primitive index: a total order, so sorts are deterministic.
bool centroid_less(const BuildRef& a, const BuildRef& b, int axis) {
    return a.centroid[axis] < b.centroid[axis] || (a.centroid[axis] == b.centroid[axis] && a.prim < b.prim);
}

struct Split {
    int axis = -1;  // -1: no split improves on a leaf, or none separates the references
    float cost = kInfinity;
    std::size_t left_count = 0;  // sweep builder: references on the left in the axis order
    int bin = 0;                 // binned builder: first bin on the right
};

// Node slots: a subtree that may hold up to n references has at most 2n - 1 nodes, so a node in slot i
// whose first child may hold n_first references puts that child in slot i + 1 and its second in slot
// i + 2 n_first. Without spatial splits n is the subtree's reference count; with them, its capacity
// (RefRange below). Subtrees built in parallel write disjoint slots, and compact() renumbers the used slots
// depth first: the layout does not depend on which task finished first.
class NodeSlots {
  public:
    explicit NodeSlots(std::size_t capacity)
        : slots_(std::allocator<BvhNode>().allocate(2 * capacity - 1), StorageDeleter{2 * capacity - 1}),
          used_(2 * capacity - 1, 0) {}

    void set_leaf(std::size_t slot, const Box3f& bounds, std::size_t first, std::size_t count) {
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.offset = static_cast<std::uint32_t>(first);
        node.prim_count = static_cast<std::uint16_t>(count);
        used_[slot] = 1;
    }
    // Returns the slots of the two children.
    std::pair<std::size_t, std::size_t> set_inner(std::size_t slot, const Box3f& bounds, int axis,
                                                  std::size_t first_child_capacity) {
        BvhNode& node = *std::construct_at(&slots_[slot]);
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.axis = static_cast<std::uint8_t>(axis);
        node.offset = static_cast<std::uint32_t>(slot + 2 * first_child_capacity);
        used_[slot] = 1;
        return {slot + 1, node.offset};
    }

    // The nodes depth first, each box grown by the scene's geometric tolerance (docs/numerical-contract.md,
    // "Boxes"), and the leaves' primitives in the same order: `prim_at(i)` is the primitive of the reference
    // at position i, which the leaves' offsets index until they are renumbered here (a spatial split build
    // leaves unused positions between its leaves); there are at most `references` of them.
    template <class PrimAt>
    [[nodiscard]] BvhBuildResult compact(PrimAt&& prim_at, std::size_t references) const {
        BvhBuildResult result;
        std::vector<BvhNode>& nodes = result.nodes;
        nodes.reserve(static_cast<std::size_t>(std::count(used_.begin(), used_.end(), 1)));
        result.prim_indices.reserve(references);
        const Vec3f margin(geometric_tolerance(slots_[0].bounds()));
        // Depth first from the root: (slot, index of the parent whose second-child offset awaits it).
        std::vector<std::pair<std::size_t, std::size_t>> pending = {{0, SIZE_MAX}};
        while (!pending.empty()) {
            const auto [slot, parent] = pending.back();
            pending.pop_back();
            if (parent != SIZE_MAX) nodes[parent].offset = static_cast<std::uint32_t>(nodes.size());
            BvhNode node = slots_[slot];
            node.lo -= margin, node.hi += margin;
            if (node.is_leaf()) {
                const std::uint32_t first = node.offset;
                node.offset = static_cast<std::uint32_t>(result.prim_indices.size());
                for (std::uint32_t i = first; i < first + node.prim_count; ++i)
                    result.prim_indices.push_back(prim_at(i));
            }
            nodes.push_back(node);
            if (!node.is_leaf()) {
                pending.push_back(
                    {node.offset, nodes.size() - 1});     // second child, after the first's subtree
                pending.push_back({slot + 1, SIZE_MAX});  // first child: the very next node
            }
        }
        return result;
    }

  private:
    // The slots are allocated, not initialised (2n - 1 of them, about twice the nodes a tree uses): a node is
    // constructed in its slot when set, and compact() reads only the nodes reached from the root.
    struct StorageDeleter {
        std::size_t count;
        void operator()(BvhNode* nodes) const { std::allocator<BvhNode>().deallocate(nodes, count); }
    };
    std::unique_ptr<BvhNode[], StorageDeleter> slots_;
    std::vector<std::uint8_t> used_;
};

// With spatial splits, the references of a build, the parts of cut primitives included, are at most this many
// times the primitives (Embree's split factor): the bound on the build's memory (docs/accel/bvh.md).
constexpr double kReferenceBudget = 1.5;

std::size_t reference_capacity(std::size_t primitives) {
    const auto budget = static_cast<std::size_t>(static_cast<double>(primitives) * kReferenceBudget);
    // Leaf offsets are 32-bit.
    return std::max(primitives, std::min<std::size_t>(budget, std::numeric_limits<std::uint32_t>::max()));
}

std::vector<BuildRef> make_refs(const Geometry& geometry) {
    std::vector<BuildRef> refs(geometry.size());
    auto make = [&](std::size_t from, std::size_t to) {
        for (auto prim = static_cast<std::uint32_t>(from); prim < to; ++prim) {
            const Box3f bounds = primitive_bounds(geometry, prim);
            refs[prim] = {bounds, bounds.center(), prim};
        }
    };
    parallel::for_each_chunk(0, refs.size(), 16384, make);
    return refs;
}

int leaf_size_limit(const BvhOptions& options) {
    return std::clamp(options.max_leaf_size, 1, BvhAccel::kMaxLeafSize);
}

// Whether a node of `count` references stays a leaf given its best split (seed 002's stopping rule: when it
// is no longer worth splitting), and never beyond the leaf size limit.
bool stays_leaf(std::size_t count, float node_area, const Split& split, int max_leaf) {
    if (count == 1) return true;
    if (count > static_cast<std::size_t>(max_leaf)) return false;
    // A node without area (references on a line or a point): no split can be told apart by the SAH.
    if (split.axis < 0 || !(node_area > 0.0f)) return true;
    return kSahNodeCost + split.cost / node_area >= static_cast<float>(count) * kSahPrimitiveCost;
}

// ---------------------------------------------------------------------------------------------------------
// Full sweep: the references are sorted once per axis by centroid (ties by primitive index); every node
// sweeps each axis right to left for the right boxes' areas, then left to right evaluating every boundary,
// and the chosen split is applied to the other two orders by a stable partition, O(N) per level.
class SweepBuilder {
  public:
    SweepBuilder(std::vector<BuildRef>& refs, const BvhOptions& options)
        : refs_(refs),
          max_leaf_(leaf_size_limit(options)),
          on_left_(refs.size()),
          right_areas_(refs.size()),
          scratch_(refs.size()) {
        for (int axis = 0; axis < 3; ++axis) {
            std::vector<std::uint32_t>& order = orders_[static_cast<std::size_t>(axis)];
            order.resize(refs.size());
            std::iota(order.begin(), order.end(), 0u);
            std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
                const float ca = refs[a].centroid[axis], cb = refs[b].centroid[axis];
                return ca < cb || (ca == cb && refs[a].prim < refs[b].prim);
            });
        }
    }

    void build(NodeSlots& slots, std::size_t slot, std::size_t begin, std::size_t end, int depth) {
        Box3f bounds;
        for (std::size_t i = begin; i < end; ++i)
            bounds.extend(refs_[orders_[0][i]].bounds);
        const std::size_t count = end - begin;
        Split split = depth >= kMedianSplitDepth ? Split{} : best_split(begin, end);
        if (stays_leaf(count, bounds.surface_area(), split, max_leaf_)) {
            slots.set_leaf(slot, bounds, begin, count);
            return;
        }
        if (split.axis < 0) split = median_split(begin, end);
        partition(begin, end, split);
        const std::size_t middle = begin + split.left_count;
        const auto [first, second] = slots.set_inner(slot, bounds, split.axis, split.left_count);
        build(slots, first, begin, middle, depth + 1);
        build(slots, second, middle, end, depth + 1);
    }

    // The primitive at position i of the leaves' ranges.
    [[nodiscard]] std::uint32_t prim_at(std::size_t i) const { return refs_[orders_[0][i]].prim; }

  private:
    Split best_split(std::size_t begin, std::size_t end) {
        Split best;
        for (int axis = 0; axis < 3; ++axis) {
            const std::vector<std::uint32_t>& order = orders_[static_cast<std::size_t>(axis)];
            Box3f right;
            for (std::size_t i = end - 1; i > begin; --i) {
                right.extend(refs_[order[i]].bounds);
                right_areas_[i] = right.surface_area();
            }
            Box3f left;
            for (std::size_t i = begin; i + 1 < end; ++i) {
                left.extend(refs_[order[i]].bounds);
                // A boundary between equal centroids would not separate anything a ray could tell apart.
                if (refs_[order[i]].centroid[axis] == refs_[order[i + 1]].centroid[axis]) continue;
                const auto left_count = i + 1 - begin;
                const float cost = left.surface_area() * static_cast<float>(left_count) +
                                   right_areas_[i + 1] * static_cast<float>(end - i - 1);
                if (cost < best.cost) best = {axis, cost, left_count, 0};
            }
        }
        return best;
    }

    // Object median on the axis of largest centroid extent: used when no boundary separates the
    // centroids, and below kMedianSplitDepth.
    Split median_split(std::size_t begin, std::size_t end) const {
        Box3f centroids;
        for (std::size_t i = begin; i < end; ++i)
            centroids.extend(refs_[orders_[0][i]].centroid);
        return {max_axis(centroids.extent()), 0.0f, (end - begin) / 2, 0};
    }

    void partition(std::size_t begin, std::size_t end, const Split& split) {
        const std::vector<std::uint32_t>& split_order = orders_[static_cast<std::size_t>(split.axis)];
        for (std::size_t i = begin; i < end; ++i)
            on_left_[split_order[i]] = i < begin + split.left_count;
        for (int axis = 0; axis < 3; ++axis) {
            if (axis == split.axis) continue;
            std::vector<std::uint32_t>& order = orders_[static_cast<std::size_t>(axis)];
            auto out = scratch_.begin();
            for (std::size_t i = begin; i < end; ++i) {
                if (on_left_[order[i]]) *out++ = order[i];
            }
            for (std::size_t i = begin; i < end; ++i) {
                if (!on_left_[order[i]]) *out++ = order[i];
            }
            std::copy(scratch_.begin(), out, order.begin() + static_cast<std::ptrdiff_t>(begin));
        }
    }

    std::vector<BuildRef>& refs_;
    int max_leaf_;
    std::array<std::vector<std::uint32_t>, 3> orders_;
    std::vector<std::uint8_t> on_left_;
    std::vector<float> right_areas_;
    std::vector<std::uint32_t> scratch_;
};

// ---------------------------------------------------------------------------------------------------------
// A node's references refs[begin, end), and the free positions [end, capacity_end) that spatial splits in
// its subtree may fill with the second parts of the references they cut (Embree's extended ranges). Without
// spatial splits there are none: capacity_end == end.
struct RefRange {
    std::size_t begin = 0, end = 0, capacity_end = 0;

    [[nodiscard]] std::size_t size() const { return end - begin; }
    [[nodiscard]] std::size_t free() const { return capacity_end - end; }
    [[nodiscard]] std::size_t capacity() const { return capacity_end - begin; }
};

// Binned SAH (Wald 2007): centroids are binned on each axis, only bin boundaries are candidates. Large nodes
// bin in parallel and large subtrees build in parallel; bin merges are exact (integer counts, min/max of
// boxes), so the result does not depend on the thread count.
//
// With spatial splits (Stich, Friedrich & Dietrich, "Spatial Splits in Bounding Volume Hierarchies", HPG
// 2009), a node whose best object split leaves overlapping children also bins its references between planes
// of its own box, each reference clipped to every bin it crosses, and may split at a plane that cuts
// references in two. The second parts go to the node's free positions, which every split shares between
// its children in proportion to their references; the whole array, hence the number of references, is
// bounded by kReferenceBudget primitives (docs/accel/bvh.md, "Spatial splits").
class BinnedBuilder {
  public:
    // A node's reference boxes' bounds and its centroids' bounds.
    using NodeBounds = std::pair<Box3f, Box3f>;

    // refs[0, primitives) are the primitives' references; the rest of `refs` is free for spatial splits.
    BinnedBuilder(std::vector<BuildRef>& refs, const Geometry& geometry, const BvhOptions& options)
        : refs_(refs),
          geometry_(geometry),
          max_leaf_(leaf_size_limit(options)),
          bins_(std::clamp(options.bins, 2, kMaxBins)),
          spatial_splits_(options.spatial_splits) {}

    void build(NodeSlots& slots, std::size_t primitives) {
        const NodeBounds root = bounds_of(0, primitives);
        min_overlap_area_ = kMinOverlap * root.first.surface_area();
        build(slots, 0, {0, primitives, refs_.size()}, 0, root);
    }

  private:
    static constexpr int kMaxBins = 256;
    static constexpr std::size_t kParallelSubtree = 4096;
    static constexpr std::size_t kParallelBinning = 65536;
    // Subtrees of at most this many references are built by SmallSubtree: the exact sweep over their sorted
    // centroids is both better and cheaper than clearing and scanning the bins.
    static constexpr std::size_t kExactSplitBelow = 32;
    // Stich et al.'s alpha ("restricting spatial split attempts"): a spatial split is tried only where the
    // object split's children overlap by more than this share of the root's area, and by at least this share
    // of the node's own area (Embree's HIGH builder asks for both).
    static constexpr float kMinOverlap = 1e-5f;
    static constexpr float kMinNodeOverlap = 0.1f;
    // Planes tried per axis by a spatial split, as Embree's SBVH builder (HeuristicArraySpatialSAH).
    static constexpr int kSpatialBins = 16;

    // An object split and its children's boxes, whose overlap decides whether a spatial split is tried.
    struct ObjectSplit {
        Split split;
        Box3f left_bounds, right_bounds;
    };

    // A spatial split: the plane on `split.axis` at boundary `split.bin` of the node's spatial bins, and the
    // children as binning saw them, which reference unsplitting weighs each cut reference against.
    struct SpatialSplit {
        Split split;
        float plane = 0.0f;
        Box3f left_bounds, right_bounds;
        std::uint32_t left_count = 0, right_count = 0;
    };

    struct Children {
        int axis = -1;
        RefRange left, right;
        NodeBounds left_bounds, right_bounds;
    };

    // A box as two 4-float rows (the fourth lane unused), so that extending one is one vector min and one
    // vector max: binning extends a bin's box three times per reference. Default construction leaves it
    // uninitialised, so that a node's Bins clear only the bins it uses; `none()` is the empty box.
    struct BinBox {
#if defined(__SSE2__)
        __m128 lo, hi;

        [[nodiscard]] static BinBox none() {
            return {_mm_set1_ps(kInfinity), _mm_set1_ps(-kInfinity)};
        }

        // A reference's box: the loads read lo.xyz and hi.x, then hi.xyz and centroid.x, all inside the
        // BuildRef; the fourth lane is never read back.
        [[nodiscard]] static BinBox of(const BuildRef& ref) {
            static_assert(offsetof(BuildRef, bounds) == 0 && offsetof(BuildRef, centroid) == sizeof(Box3f));
            return {_mm_loadu_ps(&ref.bounds.lo.x), _mm_loadu_ps(&ref.bounds.hi.x)};
        }
        // A centroid: the load reads x, y, z and the BuildRef's next field.
        [[nodiscard]] static BinBox of_point(const Vec3f& centroid) {
            static_assert(offsetof(BuildRef, prim) == offsetof(BuildRef, centroid) + sizeof(Vec3f));
            const __m128 point = _mm_loadu_ps(&centroid.x);
            return {point, point};
        }
        [[nodiscard]] static BinBox of_box(const Box3f& box) {
            return {_mm_setr_ps(box.lo.x, box.lo.y, box.lo.z, 0.0f),
                    _mm_setr_ps(box.hi.x, box.hi.y, box.hi.z, 0.0f)};
        }
        [[nodiscard]] static BinBox of_vertex(const Vec3f& point) {
            const __m128 row = _mm_setr_ps(point.x, point.y, point.z, 0.0f);
            return {row, row};
        }
        void extend(const BinBox& other) {
            lo = _mm_min_ps(other.lo, lo), hi = _mm_max_ps(other.hi, hi);
        }
        void clip(const BinBox& other) {
            lo = _mm_max_ps(other.lo, lo), hi = _mm_min_ps(other.hi, hi);
        }
        // As Box3f::empty: lo > hi, or a NaN, on some axis.
        [[nodiscard]] bool empty() const {
            return (_mm_movemask_ps(_mm_cmpnle_ps(lo, hi)) & 0b111) != 0;
        }
        // Box3f::surface_area in the same fp32 operations, (xy + yz) + zx, without leaving the registers.
        [[nodiscard]] float area() const {
            if (empty()) return 0.0f;
            const __m128 e = _mm_sub_ps(hi, lo);
            const __m128 products = _mm_mul_ps(e, _mm_shuffle_ps(e, e, _MM_SHUFFLE(3, 0, 2, 1)));
            const __m128 sum = _mm_add_ss(_mm_add_ss(products, _mm_shuffle_ps(products, products, 1)),
                                          _mm_movehl_ps(products, products));
            return 2.0f * _mm_cvtss_f32(sum);
        }
        [[nodiscard]] Box3f box() const {
            alignas(16) float low[4], high[4];
            _mm_store_ps(low, lo), _mm_store_ps(high, hi);
            return {{low[0], low[1], low[2]}, {high[0], high[1], high[2]}};
        }
#else
        Box3f bounds;

        [[nodiscard]] static BinBox none() {
            return {};
        }
        [[nodiscard]] static BinBox of(const BuildRef& ref) {
            return {ref.bounds};
        }
        [[nodiscard]] static BinBox of_point(const Vec3f& centroid) {
            return {{centroid, centroid}};
        }
        [[nodiscard]] static BinBox of_box(const Box3f& box) {
            return {box};
        }
        [[nodiscard]] static BinBox of_vertex(const Vec3f& point) {
            return {{point, point}};
        }
        void extend(const BinBox& other) {
            bounds.extend(other.bounds);
        }
        void clip(const BinBox& other) {
            bounds = intersection(bounds, other.bounds);
        }
        [[nodiscard]] bool empty() const {
            return bounds.empty();
        }
        [[nodiscard]] float area() const {
            return bounds.surface_area();
        }
        [[nodiscard]] Box3f box() const {
            return bounds;
        }
#endif
    };

    // Per axis, each bin's box and reference count; the first bins_ entries are used.
    struct Bins {
        std::array<std::array<BinBox, kMaxBins>, 3> boxes;
        std::array<std::array<std::uint32_t, kMaxBins>, 3> counts;

        explicit Bins(int bin_count) {
            for (std::size_t axis = 0; axis < 3; ++axis) {
                std::fill_n(boxes[axis].begin(), bin_count, BinBox::none());
                std::fill_n(counts[axis].begin(), bin_count, 0u);
            }
        }
        void merge(const Bins& other, int bin_count) {
            for (std::size_t axis = 0; axis < 3; ++axis) {
                for (std::size_t b = 0; b < static_cast<std::size_t>(bin_count); ++b) {
                    boxes[axis][b].extend(other.boxes[axis][b]);
                    counts[axis][b] += other.counts[axis][b];
                }
            }
        }
    };

    // The bin of a centroid on each axis: a multiplication by bins / extent, computed once per node (Wald
    // 2007, section 3.2). Binning and partitioning use the same function, so they agree on every reference.
    struct BinMap {
        Vec3f origin, scale;
        int bins;

        BinMap(const Box3f& centroids, int bin_count) : origin(centroids.lo), bins(bin_count) {
            for (int axis = 0; axis < 3; ++axis) {
                const float extent = centroids.hi[axis] - centroids.lo[axis];
                scale[axis] = extent > 0.0f ? static_cast<float>(bin_count) / extent : 0.0f;
            }
        }
        [[nodiscard]] int bin(Vec3f centroid, int axis) const {
            const float scaled = (centroid[axis] - origin[axis]) * scale[axis];
            return std::clamp(static_cast<int>(scaled), 0, bins - 1);
        }
    };

    // Two-pointer partition by the split's bin, which accumulates both sides' boxes and centroid bounds on
    // the way: the children's NodeBounds without another pass over their references.
    std::tuple<std::size_t, NodeBounds, NodeBounds> partition(std::size_t begin, std::size_t end,
                                                              const BinMap& map, const Split& split) {
        BinBox left_boxes = BinBox::none(), right_boxes = BinBox::none();
        BinBox left_centroids = BinBox::none(), right_centroids = BinBox::none();
        auto goes_left = [&](const BuildRef& ref) { return map.bin(ref.centroid, split.axis) < split.bin; };
        auto add = [](BinBox& boxes, BinBox& centroids, const BuildRef& ref) {
            boxes.extend(BinBox::of(ref));
            centroids.extend(BinBox::of_point(ref.centroid));
        };
        std::size_t i = begin, j = end;
        while (true) {
            for (; i < j && goes_left(refs_[i]); ++i)
                add(left_boxes, left_centroids, refs_[i]);
            for (; i < j && !goes_left(refs_[j - 1]); --j)
                add(right_boxes, right_centroids, refs_[j - 1]);
            if (i >= j) break;
            std::swap(refs_[i], refs_[j - 1]);
            add(left_boxes, left_centroids, refs_[i++]);
            add(right_boxes, right_centroids, refs_[--j]);
        }
        return {i, {left_boxes.box(), left_centroids.box()}, {right_boxes.box(), right_centroids.box()}};
    }

    NodeBounds bounds_of(std::size_t begin, std::size_t end) const {
        auto accumulate = [this](std::size_t from, std::size_t to, NodeBounds acc) {
            for (std::size_t i = from; i < to; ++i)
                acc.first.extend(refs_[i].bounds), acc.second.extend(refs_[i].centroid);
            return acc;
        };
        if (end - begin > kParallelBinning) {
            return parallel::reduce(begin, end, 1, NodeBounds{}, accumulate,
                                    [](NodeBounds a, const NodeBounds& b) {
                                        a.first.extend(b.first), a.second.extend(b.second);
                                        return a;
                                    });
        }
        return accumulate(begin, end, {});
    }

    // Fills `bins` (made empty by the caller). An out parameter, not a returned value: GCC does not elide
    // the copy of a returned Bins (27 KB, every node) from a function with two returns.
    void bin(std::size_t begin, std::size_t end, const BinMap& map, const Box3f& centroids,
             Bins& bins) const {
        std::array<bool, 3> splittable{};
        for (int axis = 0; axis < 3; ++axis)
            splittable[static_cast<std::size_t>(axis)] = centroids.hi[axis] > centroids.lo[axis];
        auto fill = [&](std::size_t from, std::size_t to, Bins& into) {
            for (std::size_t i = from; i < to; ++i) {
                const BuildRef& ref = refs_[i];
                const BinBox box = BinBox::of(ref);
                for (std::size_t axis = 0; axis < 3; ++axis) {
                    if (!splittable[axis]) continue;
                    const auto b = static_cast<std::size_t>(map.bin(ref.centroid, static_cast<int>(axis)));
                    into.boxes[axis][b].extend(box);
                    ++into.counts[axis][b];
                }
            }
        };
        if (end - begin > kParallelBinning) {
            bins = parallel::reduce(
                begin, end, 16384, Bins(bins_),
                [&](std::size_t from, std::size_t to, Bins chunk) {
                    fill(from, to, chunk);
                    return chunk;
                },
                [this](Bins a, const Bins& b) {
                    a.merge(b, bins_);
                    return a;
                });
            return;
        }
        fill(begin, end, bins);
    }

    ObjectSplit best_split(std::size_t begin, std::size_t end, const BinMap& map,
                           const Box3f& centroids) const {
        Bins bins(bins_);
        bin(begin, end, map, centroids, bins);
        Split best;
        std::array<float, kMaxBins> right_costs{};
        for (int axis = 0; axis < 3; ++axis) {
            if (!(centroids.hi[axis] > centroids.lo[axis])) continue;
            const auto& boxes = bins.boxes[static_cast<std::size_t>(axis)];
            const auto& counts = bins.counts[static_cast<std::size_t>(axis)];
            BinBox right = BinBox::none();
            std::uint32_t right_count = 0;
            for (int b = bins_ - 1; b > 0; --b) {
                right.extend(boxes[static_cast<std::size_t>(b)]);
                right_count += counts[static_cast<std::size_t>(b)];
                right_costs[static_cast<std::size_t>(b)] = right.area() * static_cast<float>(right_count);
            }
            BinBox left = BinBox::none();
            std::uint32_t left_count = 0;
            for (int b = 1; b < bins_; ++b) {
                left.extend(boxes[static_cast<std::size_t>(b - 1)]);
                left_count += counts[static_cast<std::size_t>(b - 1)];
                if (left_count == 0 || left_count == end - begin) continue;
                const float cost =
                    left.area() * static_cast<float>(left_count) + right_costs[static_cast<std::size_t>(b)];
                if (cost < best.cost) best = {axis, cost, left_count, b};
            }
        }
        ObjectSplit object{best, {}, {}};
        if (spatial_splits_ && best.axis >= 0) {
            BinBox left = BinBox::none(), right = BinBox::none();
            for (int b = 0; b < bins_; ++b)
                (b < best.bin ? left : right).extend(bins.boxes[static_cast<std::size_t>(best.axis)][b]);
            object.left_bounds = left.box(), object.right_bounds = right.box();
        }
        return object;
    }

    // The node over refs_[range.begin, range.end), whose reference boxes and centroids `node` bounds.
    void build(NodeSlots& slots, std::size_t slot, const RefRange& range, int depth, const NodeBounds& node) {
        const auto& [bounds, centroids] = node;
        const std::size_t count = range.size();
        if (count <= kExactSplitBelow) {
            // No spatial split here: the references are large beside the node and cross most of its bins, so
            // chopped binning would cost the most per reference, for the least gain (docs/accel/bvh.md,
            // "Spatial splits": half the bunny's build time, for at most 0.5% of the SAH cost).
            SmallSubtree(*this, slots, range).build(slot, range, depth, bounds);
            return;
        }
        const BinMap map(centroids, bins_);
        ObjectSplit object;
        SpatialSplit spatial;
        if (depth < kMedianSplitDepth) {
            object = best_split(range.begin, range.end, map, centroids);
            if (worth_a_spatial_split(range, bounds, object)) spatial = best_spatial_split(range, bounds);
        }
        const bool spatial_is_better = spatial.split.cost < object.split.cost;
        if (stays_leaf(count, bounds.surface_area(), spatial_is_better ? spatial.split : object.split,
                       max_leaf_)) {
            slots.set_leaf(slot, bounds, range.begin, count);
            return;
        }
        std::optional<Children> children;
        if (spatial_is_better) children = spatial_partition(range, bounds, spatial);
        if (!children) children = object_partition(range, object.split, map, centroids);
        const auto [first, second] = slots.set_inner(slot, bounds, children->axis, children->left.capacity());
        if (count > kParallelSubtree) {
            // Init-captures: clang before 16 cannot capture structured bindings (the fuzz build uses clang).
            parallel::invoke(
                [&, first_slot = first] {
                    build(slots, first_slot, children->left, depth + 1, children->left_bounds);
                },
                [&, second_slot = second] {
                    build(slots, second_slot, children->right, depth + 1, children->right_bounds);
                });
            return;
        }
        build(slots, first, children->left, depth + 1, children->left_bounds);
        build(slots, second, children->right, depth + 1, children->right_bounds);
    }

    // The object split's children: the binned partition, or an object median when nothing separates the
    // centroids.
    Children object_partition(const RefRange& range, Split split, const BinMap& map, const Box3f& centroids) {
        const std::size_t begin = range.begin, end = range.end, count = range.size();
        Children children;
        std::size_t middle;
        if (split.axis >= 0) {
            std::tie(middle, children.left_bounds, children.right_bounds) = partition(begin, end, map, split);
        } else {
            split = {max_axis(centroids.extent()), 0.0f, count / 2, 0};
            const int median_axis = split.axis;
            std::nth_element(refs_.begin() + static_cast<std::ptrdiff_t>(begin),
                             refs_.begin() + static_cast<std::ptrdiff_t>(begin + split.left_count),
                             refs_.begin() + static_cast<std::ptrdiff_t>(end),
                             [median_axis](const BuildRef& a, const BuildRef& b) {
                                 return centroid_less(a, b, median_axis);
                             });
            middle = begin + split.left_count;
            children.left_bounds = bounds_of(begin, middle), children.right_bounds = bounds_of(middle, end);
        }
        children.axis = split.axis;
        std::tie(children.left, children.right) = share_free_positions(range, middle - begin, end - middle);
        if (children.right.begin != middle) {
            // Make room for the left child's free positions: the right child's first references move past
            // its last (Embree's moveExtentedRange), the others stay.
            const std::size_t moved = std::min(children.right.begin - middle, end - middle);
            std::copy(refs_.begin() + static_cast<std::ptrdiff_t>(middle),
                      refs_.begin() + static_cast<std::ptrdiff_t>(middle + moved),
                      refs_.begin() + static_cast<std::ptrdiff_t>(children.right.end - moved));
        }
        return children;
    }

    // The children's ranges for `left_count` then `right_count` references out of a node whose range is
    // `range`: the free positions are shared in proportion to the references (Embree's
    // setExtentedRanges), so that a child has room for spatial splits in proportion to its size.
    static std::pair<RefRange, RefRange> share_free_positions(const RefRange& range, std::size_t left_count,
                                                              std::size_t right_count) {
        const std::size_t free = range.capacity() - left_count - right_count;
        const auto left_free = std::min(
            free, static_cast<std::size_t>(static_cast<double>(free) * static_cast<double>(left_count) /
                                           static_cast<double>(left_count + right_count)));
        const std::size_t right_begin = range.begin + left_count + left_free;
        return {{range.begin, range.begin + left_count, right_begin},
                {right_begin, right_begin + right_count, range.capacity_end}};
    }

    // ---------------------------------------------------------------------------------------------------
    // A subtree of at most kExactSplitBelow references: every boundary between consecutive centroids on
    // each axis is a candidate. The three centroid orders (centroid_less) are ranked once, at the
    // subtree's root, and each split hands its children their orders by a stable partition (seed 002's
    // "trier une seule fois par axe"): ranking them again at every node took over half of the dragon's
    // build. The tree is the one that ranking at every node gives.
    class SmallSubtree {
      public:
        SmallSubtree(BinnedBuilder& builder, NodeSlots& slots, const RefRange& range)
            : builder_(builder), slots_(slots) {
            const std::size_t count = range.size();
            // Padding sorts after every reference: its key is +inf, above every centroid.
            std::array<std::uint32_t, kExactSplitBelow> prims;
            prims.fill(std::numeric_limits<std::uint32_t>::max());
            for (auto& axis_keys : keys_)
                axis_keys.fill(kInfinity);
            for (std::size_t i = 0; i < count; ++i) {
                const BuildRef& ref = builder.refs_[range.begin + i];
                refs_[i] = ref, boxes_[i] = BinBox::of(ref), prims[i] = ref.prim;
                for (std::size_t axis = 0; axis < 3; ++axis)
                    keys_[axis][i] = ref.centroid[static_cast<int>(axis)];
            }
            // Reference i goes where the count of references before it says: branch-free compares over
            // fixed-size arrays, which GCC vectorizes, where an insertion sort mispredicts half of its.
            for (std::size_t axis = 0; axis < 3; ++axis) {
                const auto& keys = keys_[axis];
                for (std::size_t i = 0; i < count; ++i) {
                    std::uint32_t rank = 0;
                    for (std::size_t j = 0; j < kExactSplitBelow; ++j) {
                        const auto below = static_cast<std::uint32_t>(keys[j] < keys[i]);
                        const auto tie = static_cast<std::uint32_t>(keys[j] == keys[i]);
                        rank += below | (tie & static_cast<std::uint32_t>(prims[j] < prims[i]));
                    }
                    orders_[axis][rank] = static_cast<std::uint8_t>(i);
                }
            }
        }

        // The node whose references are at positions [first, first + range.size()) of every order, and whose
        // references' array order is that of `arrival_axis`'s order there (its parent's split axis; -1: the
        // order they came in, for the subtree's root).
        void build(std::size_t slot, const RefRange& range, int depth, const Box3f& bounds,
                   std::size_t first = 0, int arrival_axis = -1) {
            const std::size_t count = range.size();
            Split split = depth < kMedianSplitDepth ? best_split(first, count) : Split{};
            if (stays_leaf(count, bounds.surface_area(), split, builder_.max_leaf_)) {
                slots_.set_leaf(slot, bounds, range.begin, count);
                for (std::size_t i = 0; i < count; ++i) {
                    const std::size_t local =
                        arrival_axis < 0 ? i : orders_[static_cast<std::size_t>(arrival_axis)][first + i];
                    builder_.refs_[range.begin + i] = refs_[local];
                }
                return;
            }
            // An object median when nothing separates the centroids, or past kMedianSplitDepth.
            if (split.axis < 0)
                split = {max_axis(centroid_bounds(first, count).extent()), 0.0f, count / 2, 0};
            partition(first, count, split);
            const std::size_t left_count = split.left_count, right_count = count - left_count;
            const auto [left, right] = share_free_positions(range, left_count, right_count);
            const Box3f left_bounds = bounds_of(split.axis, first, left_count);
            const Box3f right_bounds = bounds_of(split.axis, first + left_count, right_count);
            const auto [first_slot, second_slot] =
                slots_.set_inner(slot, bounds, split.axis, left.capacity());
            build(first_slot, left, depth + 1, left_bounds, first, split.axis);
            build(second_slot, right, depth + 1, right_bounds, first + left_count, split.axis);
        }

      private:
        // The node's cheapest boundary on each axis, its boxes swept four floats at a time.
        [[nodiscard]] Split best_split(std::size_t first, std::size_t count) const {
            Split best;
            std::array<float, kExactSplitBelow> right_areas{};
            for (std::size_t axis = 0; axis < 3; ++axis) {
                const std::uint8_t* order = orders_[axis].data() + first;
                const auto& keys = keys_[axis];
                BinBox right = BinBox::none();
                for (std::size_t i = count - 1; i > 0; --i) {
                    right.extend(boxes_[order[i]]);
                    right_areas[i] = right.area();
                }
                BinBox left = BinBox::none();
                for (std::size_t i = 0; i + 1 < count; ++i) {
                    left.extend(boxes_[order[i]]);
                    // A boundary between equal centroids would not separate anything a ray could tell apart.
                    if (keys[order[i]] == keys[order[i + 1]]) continue;
                    const float cost = left.area() * static_cast<float>(i + 1) +
                                       right_areas[i + 1] * static_cast<float>(count - i - 1);
                    if (cost < best.cost) best = {static_cast<int>(axis), cost, i + 1, 0};
                }
            }
            return best;
        }

        // The first split.left_count references of the split axis's order go left; every order keeps its
        // sequence on both sides.
        void partition(std::size_t first, std::size_t count, const Split& split) {
            const auto split_axis = static_cast<std::size_t>(split.axis);
            std::array<bool, kExactSplitBelow> on_left{};
            for (std::size_t i = 0; i < split.left_count; ++i)
                on_left[orders_[split_axis][first + i]] = true;
            for (std::size_t axis = 0; axis < 3; ++axis) {
                if (axis == split_axis) continue;
                std::uint8_t* order = orders_[axis].data() + first;
                std::array<std::uint8_t, kExactSplitBelow> right;
                std::size_t left_end = 0, right_end = 0;
                for (std::size_t i = 0; i < count; ++i) {
                    if (on_left[order[i]]) {
                        order[left_end++] = order[i];
                    } else {
                        right[right_end++] = order[i];
                    }
                }
                std::copy_n(right.begin(), right_end, order + left_end);
            }
        }

        // The boxes of the references at [first, first + count) of `axis`'s order, in that order: the bits
        // the binned builder's bounds_of gives over the same array.
        [[nodiscard]] Box3f bounds_of(int axis, std::size_t first, std::size_t count) const {
            Box3f bounds;
            for (std::size_t i = first; i < first + count; ++i)
                bounds.extend(refs_[orders_[static_cast<std::size_t>(axis)][i]].bounds);
            return bounds;
        }
        [[nodiscard]] Box3f centroid_bounds(std::size_t first, std::size_t count) const {
            Box3f bounds;
            for (std::size_t i = first; i < first + count; ++i)
                bounds.extend(refs_[orders_[0][i]].centroid);
            return bounds;
        }

        BinnedBuilder& builder_;
        NodeSlots& slots_;
        std::array<BuildRef, kExactSplitBelow> refs_;
        std::array<BinBox, kExactSplitBelow> boxes_;
        std::array<std::array<float, kExactSplitBelow>, 3> keys_;
        // Per axis, the subtree's references (indices into refs_) in centroid order, each node's at its own
        // positions.
        std::array<std::array<std::uint8_t, kExactSplitBelow>, 3> orders_;
    };

    // ---------------------------------------------------------------------------------------------------
    // Spatial splits (Stich et al. 2009).

    // Tried only where the node has free positions for the parts of the references it would cut, and where
    // the best object split's children overlap by more than alpha times the root's area (Stich et al.,
    // "restricting spatial split attempts": below that, a spatial split can gain little) and by a tenth of
    // the node's area.
    [[nodiscard]] bool worth_a_spatial_split(const RefRange& range, const Box3f& bounds,
                                             const ObjectSplit& object) const {
        if (!spatial_splits_ || range.free() == 0 || object.split.axis < 0) return false;
        const float overlap = intersection(object.left_bounds, object.right_bounds).surface_area();
        return overlap > min_overlap_area_ && overlap >= kMinNodeOverlap * bounds.surface_area();
    }

    // kSpatialBins bins of equal width over the node's box on each axis (not over its centroids: the planes
    // cut references, wherever their centroids lie).
    struct SpatialBinMap {
        Vec3f origin, scale, width;
        std::array<bool, 3> splittable{};

        explicit SpatialBinMap(const Box3f& bounds) : origin(bounds.lo) {
            for (int axis = 0; axis < 3; ++axis) {
                const float extent = bounds.hi[axis] - bounds.lo[axis];
                scale[axis] = extent > 0.0f ? static_cast<float>(kSpatialBins) / extent : 0.0f;
                width[axis] = extent / static_cast<float>(kSpatialBins);
                // A denormal extent gives an infinite scale, and 0 * inf a NaN bin: such an axis is not
                // split.
                splittable[static_cast<std::size_t>(axis)] = scale[axis] > 0.0f && std::isfinite(scale[axis]);
            }
        }
        [[nodiscard]] int bin(float coordinate, int axis) const {
            const float scaled = (coordinate - origin[axis]) * scale[axis];
            return std::clamp(static_cast<int>(scaled), 0, kSpatialBins - 1);
        }
        // The plane between bins boundary - 1 and boundary.
        [[nodiscard]] float plane(int boundary, int axis) const {
            return origin[axis] + width[axis] * static_cast<float>(boundary);
        }
    };

    // Per axis, each bin's box (of the references' parts inside it) and how many references enter and
    // leave there (Stich et al.'s chopped binning).
    struct SpatialBins {
        std::array<std::array<BinBox, kSpatialBins>, 3> boxes;
        std::array<std::array<std::uint32_t, kSpatialBins>, 3> entries{}, exits{};

        SpatialBins() {
            for (auto& row : boxes)
                row.fill(BinBox::none());
        }

        void merge(const SpatialBins& other) {
            for (std::size_t axis = 0; axis < 3; ++axis) {
                for (std::size_t b = 0; b < kSpatialBins; ++b) {
                    boxes[axis][b].extend(other.boxes[axis][b]);
                    entries[axis][b] += other.entries[axis][b];
                    exits[axis][b] += other.exits[axis][b];
                }
            }
        }
    };

    // A reference's primitive cut by axis-aligned planes: the exact bounds of its part between two planes
    // and inside the reference's box (Stich et al.'s chopped references). A triangle's part is the polygon
    // whose corners are the triangle's vertices between the planes and the points where its edges cross
    // them (Karras's splitReference); a crossing is set exactly on its plane, its other coordinates rounded
    // by a few ulps of the vertices' magnitude, within the node boxes' geometric tolerance
    // (docs/numerical-contract.md, "Boxes"). A sphere's part is its box cut. The primitive is read once for
    // all the planes that cut the reference.
    class ChoppedReference {
      public:
        ChoppedReference(const Geometry& geometry, const BuildRef& ref)
            : bounds_(ref.bounds), box_(BinBox::of(ref)), is_triangle_(ref.prim < geometry.triangles.size()) {
            if (!is_triangle_) return;
            const Triangle& tri = geometry.triangles[ref.prim];
            vertices_ = {tri.v0, tri.v1, tri.v2};
            for (std::size_t v = 0; v < 3; ++v)
                corners_[v] = BinBox::of_vertex(vertices_[v]);
        }

        // The points where the triangle's edges cross the plane; a vertex on the plane is not a crossing but
        // a corner of the parts on both sides.
        [[nodiscard]] BinBox crossings(int axis, float plane) const {
            BinBox points = BinBox::none();
            if (!is_triangle_) return points;
            for (std::size_t i = 0; i < 3; ++i) {
                const Vec3f& a = vertices_[i];
                const Vec3f& b = vertices_[(i + 1) % 3];
                // Strictly on both sides: b - a is not zero on the axis, and the fraction lies in [0, 1].
                if ((a[axis] < plane && plane < b[axis]) || (b[axis] < plane && plane < a[axis])) {
                    Vec3f crossing = a + ((plane - a[axis]) / (b[axis] - a[axis])) * (b - a);
                    crossing[axis] = plane;
                    points.extend(BinBox::of_vertex(crossing));
                }
            }
            return points;
        }

        // The part between the planes lo and hi on `axis` (-inf and +inf for none), given their crossings.
        [[nodiscard]] BinBox part(int axis, float lo, float hi, const BinBox& lo_crossings,
                                  const BinBox& hi_crossings) const {
            if (!is_triangle_) {
                Box3f cut = bounds_;
                cut.lo[axis] = std::max(cut.lo[axis], lo);
                cut.hi[axis] = std::min(cut.hi[axis], hi);
                return BinBox::of_box(cut);
            }
            BinBox part = lo_crossings;
            part.extend(hi_crossings);
            for (std::size_t v = 0; v < 3; ++v) {
                if (lo <= vertices_[v][axis] && vertices_[v][axis] <= hi) part.extend(corners_[v]);
            }
            part.clip(box_);
            return part;
        }

      private:
        Box3f bounds_;
        BinBox box_;
        bool is_triangle_;
        std::array<Vec3f, 3> vertices_{};
        std::array<BinBox, 3> corners_{};
    };

    void spatial_bin_reference(const BuildRef& ref, const SpatialBinMap& map, SpatialBins& bins) const {
        std::optional<ChoppedReference> chopped;
        for (int axis = 0; axis < 3; ++axis) {
            const auto a = static_cast<std::size_t>(axis);
            if (!map.splittable[a]) continue;
            const int first = map.bin(ref.bounds.lo[axis], axis), last = map.bin(ref.bounds.hi[axis], axis);
            ++bins.entries[a][static_cast<std::size_t>(first)];
            ++bins.exits[a][static_cast<std::size_t>(last)];
            if (first == last) {
                bins.boxes[a][static_cast<std::size_t>(first)].extend(BinBox::of(ref));
                continue;
            }
            // Chopped binning: the part of the primitive in each bin it crosses, each plane's crossings
            // shared by the two bins it bounds.
            if (!chopped) chopped.emplace(geometry_, ref);
            BinBox lo_crossings = BinBox::none();
            for (int b = first; b <= last; ++b) {
                const float lo = b == first ? -kInfinity : map.plane(b, axis);
                const float hi = b == last ? kInfinity : map.plane(b + 1, axis);
                const BinBox hi_crossings = b == last ? BinBox::none() : chopped->crossings(axis, hi);
                const BinBox part = chopped->part(axis, lo, hi, lo_crossings, hi_crossings);
                if (!part.empty()) bins.boxes[a][static_cast<std::size_t>(b)].extend(part);
                lo_crossings = hi_crossings;
            }
        }
    }

    // Fills `bins` (made empty by the caller), an out parameter for the reason bin() gives.
    void spatial_bin(std::size_t begin, std::size_t end, const SpatialBinMap& map, SpatialBins& bins) const {
        auto fill = [&](std::size_t from, std::size_t to, SpatialBins& into) {
            for (std::size_t i = from; i < to; ++i)
                spatial_bin_reference(refs_[i], map, into);
        };
        if (end - begin > kParallelBinning) {
            bins = parallel::reduce(
                begin, end, 16384, SpatialBins{},
                [&](std::size_t from, std::size_t to, SpatialBins chunk) {
                    fill(from, to, chunk);
                    return chunk;
                },
                [](SpatialBins a, const SpatialBins& b) {
                    a.merge(b);
                    return a;
                });
            return;
        }
        fill(begin, end, bins);
    }

    // The cheapest plane of the node's spatial bins: the left child holds every reference that enters left
    // of it, the right child every one that leaves right of it, the cut ones in both.
    SpatialSplit best_spatial_split(const RefRange& range, const Box3f& bounds) const {
        const SpatialBinMap map(bounds);
        SpatialBins bins;
        spatial_bin(range.begin, range.end, map, bins);
        SpatialSplit best;
        std::array<Box3f, kSpatialBins> right_boxes;
        std::array<std::uint32_t, kSpatialBins> right_counts{};
        for (int axis = 0; axis < 3; ++axis) {
            const auto a = static_cast<std::size_t>(axis);
            if (!map.splittable[a]) continue;
            Box3f right;
            std::uint32_t right_count = 0;
            for (std::size_t b = kSpatialBins - 1; b > 0; --b) {
                right.extend(bins.boxes[a][b].box());
                right_count += bins.exits[a][b];
                right_boxes[b] = right, right_counts[b] = right_count;
            }
            Box3f left;
            std::uint32_t left_count = 0;
            for (std::size_t b = 1; b < kSpatialBins; ++b) {
                left.extend(bins.boxes[a][b - 1].box());
                left_count += bins.entries[a][b - 1];
                if (left_count == 0 || right_counts[b] == 0) continue;
                const float cost = left.surface_area() * static_cast<float>(left_count) +
                                   right_boxes[b].surface_area() * static_cast<float>(right_counts[b]);
                if (cost < best.split.cost) {
                    best.split = {axis, cost, left_count, static_cast<int>(b)};
                    best.plane = map.plane(static_cast<int>(b), axis);
                    best.left_bounds = left, best.right_bounds = right_boxes[b];
                    best.left_count = left_count, best.right_count = right_counts[b];
                }
            }
        }
        return best;
    }

    // Applies a spatial split: a reference on one side of the plane goes to that side; one that the plane
    // cuts either goes to both sides, each with the bounds of its part, or, where that is cheaper, whole to
    // one side (Stich et al., "reference unsplitting"; the children's boxes and counts are those of the
    // binning, so that every reference's choice is independent of the others'). Cuts stop once the
    // node's free positions are used up: the remaining cut references are unsplit to their cheaper side.
    // No children (a fall back to the object split) when one side ends up empty, which the rounding of the
    // plane against the bins can cause.
    std::optional<Children> spatial_partition(const RefRange& range, const Box3f& bounds,
                                              const SpatialSplit& spatial) {
        const int axis = spatial.split.axis;
        const SpatialBinMap map(bounds);
        const float left_area = spatial.left_bounds.surface_area();
        const float right_area = spatial.right_bounds.surface_area();
        const auto left_count = static_cast<float>(spatial.left_count);
        const auto right_count = static_cast<float>(spatial.right_count);
        const float split_cost = left_area * left_count + right_area * right_count;
        std::vector<BuildRef> left, right;
        left.reserve(spatial.left_count), right.reserve(spatial.right_count);
        std::size_t cuts_left = range.free();
        for (std::size_t i = range.begin; i < range.end; ++i) {
            const BuildRef& ref = refs_[i];
            if (map.bin(ref.bounds.hi[axis], axis) < spatial.split.bin) {
                left.push_back(ref);
                continue;
            }
            if (map.bin(ref.bounds.lo[axis], axis) >= spatial.split.bin) {
                right.push_back(ref);
                continue;
            }
            const ChoppedReference chopped(geometry_, ref);
            const BinBox crossings = chopped.crossings(axis, spatial.plane);
            const Box3f left_part =
                chopped.part(axis, -kInfinity, spatial.plane, BinBox::none(), crossings).box();
            const Box3f right_part =
                chopped.part(axis, spatial.plane, kInfinity, crossings, BinBox::none()).box();
            if (left_part.empty() || right_part.empty()) {
                // The plane does not cut the primitive itself: its part on the one side is all of it.
                (left_part.empty() ? right : left)
                    .push_back(with_bounds(ref, left_part.empty() ? right_part : left_part));
                continue;
            }
            Box3f left_with_ref = spatial.left_bounds, right_with_ref = spatial.right_bounds;
            left_with_ref.extend(ref.bounds), right_with_ref.extend(ref.bounds);
            const float cost_all_left =
                left_with_ref.surface_area() * left_count + right_area * (right_count - 1.0f);
            const float cost_all_right =
                left_area * (left_count - 1.0f) + right_with_ref.surface_area() * right_count;
            if (cuts_left > 0 && split_cost <= std::min(cost_all_left, cost_all_right)) {
                --cuts_left;
                left.push_back(with_bounds(ref, left_part));
                right.push_back(with_bounds(ref, right_part));
            } else {
                (cost_all_left <= cost_all_right ? left : right).push_back(ref);
            }
        }
        if (left.empty() || right.empty()) return std::nullopt;
        Children children;
        children.axis = axis;
        std::tie(children.left, children.right) = share_free_positions(range, left.size(), right.size());
        std::copy(left.begin(), left.end(), refs_.begin() + static_cast<std::ptrdiff_t>(children.left.begin));
        std::copy(right.begin(), right.end(),
                  refs_.begin() + static_cast<std::ptrdiff_t>(children.right.begin));
        children.left_bounds = bounds_of(children.left.begin, children.left.end);
        children.right_bounds = bounds_of(children.right.begin, children.right.end);
        return children;
    }

    [[nodiscard]] static BuildRef with_bounds(const BuildRef& ref, const Box3f& bounds) {
        return {bounds, bounds.center(), ref.prim};
    }

    std::vector<BuildRef>& refs_;
    const Geometry& geometry_;
    int max_leaf_;
    int bins_;
    bool spatial_splits_;
    float min_overlap_area_ = 0.0f;
};

}  // namespace

BvhBuildResult build_bvh(const Geometry& geometry, const BvhOptions& options) {
    if (geometry.size() == 0) return {};
    std::vector<BuildRef> refs = make_refs(geometry);
    const std::size_t primitives = refs.size();
    BvhBuildResult result;
    if (options.builder == BvhBuilder::SweepSah) {
        NodeSlots slots(primitives);
        SweepBuilder builder(refs, options);
        builder.build(slots, 0, 0, primitives, 0);
        result = slots.compact([&](std::size_t i) { return builder.prim_at(i); }, primitives);
    } else {
        if (options.spatial_splits) refs.resize(reference_capacity(primitives));
        NodeSlots slots(refs.size());
        BinnedBuilder builder(refs, geometry, options);
        builder.build(slots, primitives);
        result = slots.compact([&](std::size_t i) { return refs[i].prim; }, refs.size());
    }
    return result;
}

double bvh_sah_cost(const std::vector<BvhNode>& nodes) {
    if (nodes.empty()) return 0.0;
    const double root_area = nodes[0].bounds().surface_area();
    double weighted_area = 0.0;
    std::size_t references = 0;
    for (const BvhNode& node : nodes) {
        const double area = node.bounds().surface_area();
        weighted_area += node.is_leaf() ? area * node.prim_count * kSahPrimitiveCost : area * kSahNodeCost;
        references += node.prim_count;
    }
    // A tree whose root has no area costs its primitive references.
    return root_area > 0.0 ? weighted_area / root_area : static_cast<double>(references);
}

}  // namespace lancer
