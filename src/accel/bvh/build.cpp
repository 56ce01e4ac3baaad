#include "accel/bvh/build.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <limits>
#include <numeric>
#include <tuple>

#include "accel/build_util.hpp"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#if LANCER_HAS_TBB
#include <tbb/blocked_range.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>
#endif

namespace lancer {
namespace {

// The SAH of seed 002: T(child) = T_box + A(child) / A(node) N(child) T_object, with T_box = T_object = 1.
constexpr float kNodeCost = 1.0f;
constexpr float kPrimitiveCost = 1.0f;
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

// Node slots: a subtree over n references has at most 2n - 1 nodes, so a node in slot i over n references
// puts its first child in slot i + 1 and its second in slot i + 2 n_first. Subtrees built in parallel write
// disjoint slots, and compact() renumbers the used slots depth first: the layout does not depend on which
// task finished first.
class NodeSlots {
  public:
    explicit NodeSlots(std::size_t references) : slots_(2 * references - 1), used_(2 * references - 1, 0) {}

    void set_leaf(std::size_t slot, const Box3f& bounds, std::size_t first, std::size_t count) {
        BvhNode& node = slots_[slot];
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.offset = static_cast<std::uint32_t>(first);
        node.prim_count = static_cast<std::uint16_t>(count);
        used_[slot] = 1;
    }
    // Returns the slots of the two children.
    std::pair<std::size_t, std::size_t> set_inner(std::size_t slot, const Box3f& bounds, int axis,
                                                  std::size_t first_child_references) {
        BvhNode& node = slots_[slot];
        node.lo = bounds.lo, node.hi = bounds.hi;
        node.axis = static_cast<std::uint8_t>(axis);
        node.offset = static_cast<std::uint32_t>(slot + 2 * first_child_references);
        used_[slot] = 1;
        return {slot + 1, node.offset};
    }

    [[nodiscard]] std::vector<BvhNode> compact() const {
        std::vector<BvhNode> nodes;
        nodes.reserve(static_cast<std::size_t>(std::count(used_.begin(), used_.end(), 1)));
        // Depth first from the root: (slot, index of the parent whose second-child offset awaits it).
        std::vector<std::pair<std::size_t, std::size_t>> pending = {{0, SIZE_MAX}};
        while (!pending.empty()) {
            const auto [slot, parent] = pending.back();
            pending.pop_back();
            if (parent != SIZE_MAX) nodes[parent].offset = static_cast<std::uint32_t>(nodes.size());
            const BvhNode& node = slots_[slot];
            nodes.push_back(node);
            if (!node.is_leaf()) {
                pending.push_back(
                    {node.offset, nodes.size() - 1});     // second child, after the first's subtree
                pending.push_back({slot + 1, SIZE_MAX});  // first child: the very next node
            }
        }
        return nodes;
    }

  private:
    std::vector<BvhNode> slots_;
    std::vector<std::uint8_t> used_;
};

std::vector<BuildRef> make_refs(const Geometry& geometry) {
    std::vector<BuildRef> refs(geometry.size());
    for (std::uint32_t prim = 0; prim < refs.size(); ++prim) {
        const Box3f bounds = primitive_bounds(geometry, prim);
        refs[prim] = {bounds, bounds.center(), prim};
    }
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
    return kNodeCost + split.cost / node_area >= static_cast<float>(count) * kPrimitiveCost;
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

    [[nodiscard]] std::vector<std::uint32_t> prim_indices() const {
        std::vector<std::uint32_t> prims(refs_.size());
        for (std::size_t i = 0; i < prims.size(); ++i)
            prims[i] = refs_[orders_[0][i]].prim;
        return prims;
    }

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
// Binned SAH (Wald 2007): centroids are binned on each axis, only bin boundaries are candidates. Large nodes
// bin in parallel and large subtrees build in parallel; bin merges are exact (integer counts, min/max of
// boxes), so the result does not depend on the thread count.
class BinnedBuilder {
  public:
    // A node's reference boxes' bounds and its centroids' bounds.
    using NodeBounds = std::pair<Box3f, Box3f>;

    BinnedBuilder(std::vector<BuildRef>& refs, const BvhOptions& options)
        : refs_(refs), max_leaf_(leaf_size_limit(options)), bins_(std::clamp(options.bins, 2, kMaxBins)) {}

    // The node over refs_[begin, end), whose reference boxes and centroids `node` bounds.
    void build(NodeSlots& slots, std::size_t slot, std::size_t begin, std::size_t end, int depth,
               const NodeBounds& node) {
        const auto& [bounds, centroids] = node;
        const std::size_t count = end - begin;
        const bool exact = count <= kExactSplitBelow;
        const BinMap map(centroids, bins_);
        Split split;
        ExactOrder exact_order;
        if (depth < kMedianSplitDepth)
            split = exact ? exact_split(begin, end, exact_order) : best_split(begin, end, map, centroids);
        if (stays_leaf(count, bounds.surface_area(), split, max_leaf_)) {
            slots.set_leaf(slot, bounds, begin, count);
            return;
        }
        std::size_t middle;
        NodeBounds left, right;
        if (split.axis >= 0 && !exact) {
            std::tie(middle, left, right) = partition(begin, end, map, split);
        } else {
            if (split.axis >= 0) {
                // The exact split's order on its axis.
                std::array<BuildRef, kExactSplitBelow> node_refs;
                std::copy(refs_.begin() + static_cast<std::ptrdiff_t>(begin),
                          refs_.begin() + static_cast<std::ptrdiff_t>(end), node_refs.begin());
                for (std::size_t i = 0; i < count; ++i)
                    refs_[begin + i] = node_refs[exact_order[i]];
            } else {
                // An object median when nothing separates the centroids.
                split = {max_axis(centroids.extent()), 0.0f, count / 2, 0};
                const int axis = split.axis;
                std::nth_element(
                    refs_.begin() + static_cast<std::ptrdiff_t>(begin),
                    refs_.begin() + static_cast<std::ptrdiff_t>(begin + split.left_count),
                    refs_.begin() + static_cast<std::ptrdiff_t>(end),
                    [axis](const BuildRef& a, const BuildRef& b) { return centroid_less(a, b, axis); });
            }
            middle = begin + split.left_count;
            left = bounds_of(begin, middle), right = bounds_of(middle, end);
        }
        const auto [first, second] = slots.set_inner(slot, bounds, split.axis, middle - begin);
#if LANCER_HAS_TBB
        if (count > kParallelSubtree) {
            // Init-captures: clang before 16 cannot capture structured bindings (the fuzz build uses clang).
            tbb::parallel_invoke(
                [&, first_slot = first] { build(slots, first_slot, begin, middle, depth + 1, left); },
                [&, second_slot = second] { build(slots, second_slot, middle, end, depth + 1, right); });
            return;
        }
#endif
        build(slots, first, begin, middle, depth + 1, left);
        build(slots, second, middle, end, depth + 1, right);
    }

    // The whole reference array's node.
    void build(NodeSlots& slots) {
        build(slots, 0, 0, refs_.size(), 0, bounds_of(0, refs_.size()));
    }

  private:
    static constexpr int kMaxBins = 256;
    static constexpr std::size_t kParallelSubtree = 4096;
    static constexpr std::size_t kParallelBinning = 65536;
    // Below this many references, the exact sweep over the node's own sorted centroids is both better and
    // cheaper than clearing and scanning the bins.
    static constexpr std::size_t kExactSplitBelow = 32;

    // Offsets from a node's first reference, for the exact split's orders.
    using ExactOrder = std::array<std::uint8_t, kExactSplitBelow>;

    // Every boundary between consecutive centroids on each axis, in centroid order (ties by primitive
    // index), for a node of at most kExactSplitBelow references; `best_order` receives the order of the
    // chosen axis, which the caller applies (no second sort to partition), and the boxes are swept four
    // floats at a time.
    Split exact_split(std::size_t begin, std::size_t end, ExactOrder& best_order) const {
        const std::size_t count = end - begin;
        std::array<BinBox, kExactSplitBelow> boxes;
        // Padding past `count` sorts after every reference: its key is +inf, above every centroid.
        std::array<float, kExactSplitBelow> keys;
        std::array<std::uint32_t, kExactSplitBelow> prims;
        keys.fill(kInfinity);
        prims.fill(std::numeric_limits<std::uint32_t>::max());
        for (std::size_t i = 0; i < count; ++i) {
            const BuildRef& ref = refs_[begin + i];
            boxes[i] = BinBox::of(ref);
            prims[i] = ref.prim;
        }
        ExactOrder order;
        std::array<float, kExactSplitBelow> right_areas{};
        Split best;
        for (int axis = 0; axis < 3; ++axis) {
            for (std::size_t i = 0; i < count; ++i)
                keys[i] = refs_[begin + i].centroid[axis];
            // centroid_less's order by ranks: reference i goes where the count of references before it says.
            // Branch-free compares over fixed-size arrays, where an insertion sort mispredicts half of its.
            for (std::size_t i = 0; i < count; ++i) {
                std::uint32_t rank = 0;
                for (std::size_t j = 0; j < kExactSplitBelow; ++j) {
                    rank += static_cast<std::uint32_t>((keys[j] < keys[i]) |
                                                       ((keys[j] == keys[i]) & (prims[j] < prims[i])));
                }
                order[rank] = static_cast<std::uint8_t>(i);
            }
            BinBox right;
            for (std::size_t i = count - 1; i > 0; --i) {
                right.extend(boxes[order[i]]);
                right_areas[i] = right.box().surface_area();
            }
            BinBox left;
            bool improved = false;
            for (std::size_t i = 0; i + 1 < count; ++i) {
                left.extend(boxes[order[i]]);
                if (keys[order[i]] == keys[order[i + 1]]) continue;
                const float cost = left.box().surface_area() * static_cast<float>(i + 1) +
                                   right_areas[i + 1] * static_cast<float>(count - i - 1);
                if (cost < best.cost) best = {axis, cost, i + 1, 0}, improved = true;
            }
            if (improved) best_order = order;
        }
        return best;
    }

    // A box as two 4-float rows (the fourth lane unused), so that extending one is one vector min and one
    // vector max: binning extends a bin's box three times per reference.
    struct BinBox {
#if defined(__SSE2__)
        __m128 lo = _mm_set1_ps(kInfinity);
        __m128 hi = _mm_set1_ps(-kInfinity);

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
        void extend(const BinBox& other) {
            lo = _mm_min_ps(other.lo, lo), hi = _mm_max_ps(other.hi, hi);
        }
        [[nodiscard]] Box3f box() const {
            alignas(16) float low[4], high[4];
            _mm_store_ps(low, lo), _mm_store_ps(high, hi);
            return {{low[0], low[1], low[2]}, {high[0], high[1], high[2]}};
        }
#else
        Box3f bounds;

        [[nodiscard]] static BinBox of(const BuildRef& ref) {
            return {ref.bounds};
        }
        [[nodiscard]] static BinBox of_point(const Vec3f& centroid) {
            return {{centroid, centroid}};
        }
        void extend(const BinBox& other) {
            bounds.extend(other.bounds);
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
                std::fill_n(boxes[axis].begin(), bin_count, BinBox{});
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
        BinBox left_boxes, right_boxes, left_centroids, right_centroids;
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
#if LANCER_HAS_TBB
        if (end - begin > kParallelBinning) {
            return tbb::parallel_reduce(
                tbb::blocked_range<std::size_t>(begin, end), NodeBounds{},
                [&](const tbb::blocked_range<std::size_t>& r, NodeBounds acc) {
                    return accumulate(r.begin(), r.end(), acc);
                },
                [](NodeBounds a, const NodeBounds& b) {
                    a.first.extend(b.first), a.second.extend(b.second);
                    return a;
                });
        }
#endif
        return accumulate(begin, end, {});
    }

    Bins bin(std::size_t begin, std::size_t end, const BinMap& map, const Box3f& centroids) const {
        std::array<bool, 3> splittable{};
        for (int axis = 0; axis < 3; ++axis)
            splittable[static_cast<std::size_t>(axis)] = centroids.hi[axis] > centroids.lo[axis];
        auto fill = [&](std::size_t from, std::size_t to, Bins& bins) {
            for (std::size_t i = from; i < to; ++i) {
                const BuildRef& ref = refs_[i];
                const BinBox box = BinBox::of(ref);
                for (std::size_t axis = 0; axis < 3; ++axis) {
                    if (!splittable[axis]) continue;
                    const auto b = static_cast<std::size_t>(map.bin(ref.centroid, static_cast<int>(axis)));
                    bins.boxes[axis][b].extend(box);
                    ++bins.counts[axis][b];
                }
            }
        };
#if LANCER_HAS_TBB
        if (end - begin > kParallelBinning) {
            return tbb::parallel_reduce(
                tbb::blocked_range<std::size_t>(begin, end, 16384), Bins(bins_),
                [&](const tbb::blocked_range<std::size_t>& r, Bins bins) {
                    fill(r.begin(), r.end(), bins);
                    return bins;
                },
                [this](Bins a, const Bins& b) {
                    a.merge(b, bins_);
                    return a;
                });
        }
#endif
        Bins bins(bins_);
        fill(begin, end, bins);
        return bins;
    }

    Split best_split(std::size_t begin, std::size_t end, const BinMap& map, const Box3f& centroids) const {
        const Bins bins = bin(begin, end, map, centroids);
        Split best;
        std::array<float, kMaxBins> right_costs{};
        for (int axis = 0; axis < 3; ++axis) {
            if (!(centroids.hi[axis] > centroids.lo[axis])) continue;
            const auto& boxes = bins.boxes[static_cast<std::size_t>(axis)];
            const auto& counts = bins.counts[static_cast<std::size_t>(axis)];
            Box3f right;
            std::uint32_t right_count = 0;
            for (int b = bins_ - 1; b > 0; --b) {
                right.extend(boxes[static_cast<std::size_t>(b)].box());
                right_count += counts[static_cast<std::size_t>(b)];
                right_costs[static_cast<std::size_t>(b)] =
                    right.surface_area() * static_cast<float>(right_count);
            }
            Box3f left;
            std::uint32_t left_count = 0;
            for (int b = 1; b < bins_; ++b) {
                left.extend(boxes[static_cast<std::size_t>(b - 1)].box());
                left_count += counts[static_cast<std::size_t>(b - 1)];
                if (left_count == 0 || left_count == end - begin) continue;
                const float cost = left.surface_area() * static_cast<float>(left_count) +
                                   right_costs[static_cast<std::size_t>(b)];
                if (cost < best.cost) best = {axis, cost, left_count, b};
            }
        }
        return best;
    }

    std::vector<BuildRef>& refs_;
    int max_leaf_;
    int bins_;
};

}  // namespace

BvhBuildResult build_bvh(const Geometry& geometry, const BvhOptions& options) {
    BvhBuildResult result;
    if (geometry.size() == 0) return result;
    std::vector<BuildRef> refs = make_refs(geometry);
    NodeSlots slots(refs.size());
    if (options.builder == BvhBuilder::SweepSah) {
        SweepBuilder builder(refs, options);
        builder.build(slots, 0, 0, refs.size(), 0);
        result.prim_indices = builder.prim_indices();
    } else {
        BinnedBuilder builder(refs, options);
        builder.build(slots);
        result.prim_indices.resize(refs.size());
        for (std::size_t i = 0; i < refs.size(); ++i)
            result.prim_indices[i] = refs[i].prim;
    }
    result.nodes = slots.compact();
    const Vec3f margin(geometric_tolerance(result.nodes[0].bounds()));
    for (BvhNode& node : result.nodes)
        node.lo -= margin, node.hi += margin;
    return result;
}

double bvh_sah_cost(const std::vector<BvhNode>& nodes) {
    if (nodes.empty()) return 0.0;
    const double root_area = nodes[0].bounds().surface_area();
    if (!(root_area > 0.0)) return static_cast<double>(nodes[0].prim_count);
    double cost = 0.0;
    for (const BvhNode& node : nodes) {
        const double relative_area = node.bounds().surface_area() / root_area;
        cost += node.is_leaf() ? relative_area * node.prim_count * kPrimitiveCost : relative_area * kNodeCost;
    }
    return cost;
}

}  // namespace lancer
