// The binned SAH builder: centroid bins, the split at the cheapest bin boundary, and the recursion that hands
// large nodes to spatial splits (spatial_splits.cpp) and small ones to SmallSubtree (small_subtree.cpp).
#include "accel/bvh/binned_builder.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <tuple>
#include <type_traits>
#include <vector>

#include "accel/bvh/bin_box.hpp"
#include "accel/bvh/pair_partition.hpp"
#include "accel/bvh/small_subtree.hpp"
#include "core/parallel.hpp"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace lancer {

// Per axis, each bin's box and reference count; the first bins_ entries are used.
struct BinnedBuilder::Bins {
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
struct BinnedBuilder::BinMap {
    Vec3f origin, scale;
    int bins;
    float last_bin;

    BinMap(const Box3f& centroids, int bin_count)
        : origin(centroids.lo), bins(bin_count), last_bin(static_cast<float>(bin_count - 1)) {
        for (int axis = 0; axis < 3; ++axis) {
            const float extent = centroids.hi[axis] - centroids.lo[axis];
            scale[axis] = extent > 0.0f ? static_cast<float>(bin_count) / extent : 0.0f;
        }
    }
    // (centroid - origin) * scale on the axis, clamped to the bins before the conversion, so that no
    // converted value is out of range. The scale is infinite only for extents below bins * 2^-128; a centroid
    // at the origin then scales to NaN, which the clamp's first comparison makes 0.
    [[nodiscard]] std::ptrdiff_t bin(Vec3f centroid, int axis) const {
#if defined(__SSE2__) && defined(__x86_64__)
        // In scalar SSE: GCC compiles the comparisons below to compares and blends (for their NaN and
        // signed-zero cases), where maxss and minss give the same.
        const __m128 scaled = _mm_mul_ss(_mm_sub_ss(_mm_set_ss(centroid[axis]), _mm_set_ss(origin[axis])),
                                         _mm_set_ss(scale[axis]));
        const __m128 at_least_0 = _mm_max_ss(scaled, _mm_setzero_ps());
        return _mm_cvttss_si64(_mm_min_ss(at_least_0, _mm_set_ss(last_bin)));
#else
        const float scaled = (centroid[axis] - origin[axis]) * scale[axis];
        const float at_least_0 = scaled > 0.0f ? scaled : 0.0f;
        return static_cast<std::ptrdiff_t>(at_least_0 < last_bin ? at_least_0 : last_bin);
#endif
    }
};

namespace {

// f(std::integral_constant<int, axis>()) for an axis known at run time: a loop over references whose axis is
// a constant reads the coordinate without Vec3f::operator[]'s select on every reference.
template <class F>
void with_axis(int axis, F&& f) {
    switch (axis) {
        case 0:
            return f(std::integral_constant<int, 0>());
        case 1:
            return f(std::integral_constant<int, 1>());
        default:
            return f(std::integral_constant<int, 2>());
    }
}

}  // namespace

BinnedBuilder::BinnedBuilder(BuildRefs& refs, const Geometry& geometry, const BvhOptions& options,
                             std::size_t whole_leaf_size)
    : refs_(refs),
      geometry_(geometry),
      max_leaf_(leaf_size_limit(options)),
      whole_leaf_size_(whole_leaf_size),
      bins_(std::clamp(options.bins, 2, kMaxBins)),
      spatial_splits_(options.spatial_splits),
      per_position_(uninitialised_huge_pages<std::uint32_t>(refs.size())) {}

void BinnedBuilder::build(NodeSlots& slots, std::size_t primitives) {
    const NodeBounds root = bounds_of(0, primitives);
    min_overlap_area_ = kMinOverlap * root.first.surface_area();
    build(slots, 0, {0, primitives, refs_.size()}, 0, root);
}

// The two-pointer partition by the split's bin, as pair_partition makes it (in parallel over large nodes),
// which accumulates both sides' centroid bounds on the way. Their boxes need no pass: each side's is the
// union of its bins' boxes on the split's axis (ObjectSplit), since partition and binning put every
// reference on the same side of the split's bin.
std::tuple<std::size_t, Box3f, Box3f> BinnedBuilder::partition(std::size_t begin, std::size_t end,
                                                               const BinMap& map, const Split& split) {
    struct SideCentroids {
        BinBox left = BinBox::none(), right = BinBox::none();

        bool add(const BuildRef& ref, bool goes_left) {
            BinBox::extend_either(left, right, BinBox::of_point(ref.centroid), goes_left);
            return goes_left;
        }
        void merge(const SideCentroids& other) { left.extend(other.left), right.extend(other.right); }
    };
    // The map and the split's bin as locals (the scratch's stores could alias the split's int), and the axis
    // a constant in each of the three loops: the same bins as map.bin, with fewer loads per reference.
    const BinMap local_map = map;
    const std::ptrdiff_t split_bin = split.bin;
    const std::size_t count = end - begin;
    BuildRef* const refs = refs_.data() + begin;
    std::uint32_t* const scratch = per_position_.get() + begin;
    SideCentroids sides;
    std::size_t middle = 0;
    with_axis(split.axis, [&](auto axis) {
        auto goes_left = [&](const BuildRef& ref) { return local_map.bin(ref.centroid, axis) < split_bin; };
        if (count <= kParallelBinning) {
            // One block, its bounds in registers.
            middle = pair_partition(
                refs, count, count, scratch,
                [&](std::size_t /*block*/, const BuildRef& ref) { return sides.add(ref, goes_left(ref)); });
            return;
        }
        std::vector<SideCentroids> per_block((count + kBinningChunk - 1) / kBinningChunk);
        middle =
            pair_partition(refs, count, kBinningChunk, scratch, [&](std::size_t block, const BuildRef& ref) {
                return per_block[block].add(ref, goes_left(ref));
            });
        // Merged in block order: the same bits whatever the threads.
        for (const SideCentroids& block : per_block)
            sides.merge(block);
    });
    return {begin + middle, sides.left.box(), sides.right.box()};
}

BinnedBuilder::NodeBounds BinnedBuilder::bounds_of(std::size_t begin, std::size_t end) const {
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
// Every axis is binned, without a branch: an axis whose centroids have no extent (which best_split skips)
// scales to 0, so its references all fall in bin 0.
void BinnedBuilder::bin(std::size_t begin, std::size_t end, const BinMap& map, Bins& bins) const {
    // The map as a local, as in partition: the bins' stores cannot alias it, so its fields stay in registers.
    const BinMap local_map = map;
    const BuildRef* const refs = refs_.data();
    auto fill = [&](std::size_t from, std::size_t to, Bins& into) {
        for (std::size_t i = from; i < to; ++i) {
            const BuildRef& ref = refs[i];
            const BinBox box = BinBox::of(ref);
            for (std::size_t axis = 0; axis < 3; ++axis) {
                const auto b = static_cast<std::size_t>(local_map.bin(ref.centroid, static_cast<int>(axis)));
                into.boxes[axis][b].extend(box);
                ++into.counts[axis][b];
            }
        }
    };
    if (end - begin > kParallelBinning) {
        // Each chunk bins into its own Bins on its stack, merged into the node's under a lock: merges are
        // exact (counts, min and max), so their order does not matter, and no 27 KB Bins is copied, as a
        // reduction's partial results passed by value were (docs/accel/bvh.md, "Build speed").
        std::mutex merging;
        parallel::for_each_chunk(begin, end, kBinningChunk, [&](std::size_t from, std::size_t to) {
            Bins chunk(map.bins);
            fill(from, to, chunk);
            const std::lock_guard lock(merging);
            bins.merge(chunk, map.bins);
        });
        return;
    }
    fill(begin, end, bins);
}

BinnedBuilder::ObjectSplit BinnedBuilder::best_split(std::size_t begin, std::size_t end, const BinMap& map,
                                                     const Box3f& centroids) const {
    Bins bins(map.bins);
    bin(begin, end, map, bins);
    Split best;
    std::array<float, kMaxBins> right_costs;
    for (int axis = 0; axis < 3; ++axis) {
        if (!(centroids.hi[axis] > centroids.lo[axis])) continue;
        const auto& boxes = bins.boxes[static_cast<std::size_t>(axis)];
        const auto& counts = bins.counts[static_cast<std::size_t>(axis)];
        BinBox right = BinBox::none();
        std::uint32_t right_count = 0;
        for (int b = map.bins - 1; b > 0; --b) {
            right.extend(boxes[static_cast<std::size_t>(b)]);
            right_count += counts[static_cast<std::size_t>(b)];
            // filled_area: a side without references (an infinite area) is never weighed, as the loop
            // below skips the splits that leave a side empty.
            right_costs[static_cast<std::size_t>(b)] = right.filled_area() * static_cast<float>(right_count);
        }
        BinBox left = BinBox::none();
        std::uint32_t left_count = 0;
        for (int b = 1; b < map.bins; ++b) {
            left.extend(boxes[static_cast<std::size_t>(b - 1)]);
            left_count += counts[static_cast<std::size_t>(b - 1)];
            if (left_count == 0 || left_count == end - begin) continue;
            const float cost = left.filled_area() * static_cast<float>(left_count) +
                               right_costs[static_cast<std::size_t>(b)];
            if (cost < best.cost) best = {axis, cost, left_count, b};
        }
    }
    ObjectSplit object{best, {}, {}};
    if (best.axis >= 0) {
        BinBox left = BinBox::none(), right = BinBox::none();
        for (int b = 0; b < map.bins; ++b)
            (b < best.bin ? left : right).extend(bins.boxes[static_cast<std::size_t>(best.axis)][b]);
        object.left_bounds = left.box(), object.right_bounds = right.box();
    }
    return object;
}

void BinnedBuilder::build(NodeSlots& slots, std::size_t slot, const RefRange& range, int depth,
                          const NodeBounds& node) {
    const auto& [bounds, centroids] = node;
    const std::size_t count = range.size();
    if (count <= whole_leaf_size_) {
        set_leaf(slots, slot, bounds, range);
        return;
    }
    if (count <= kExactSplitBelow) {
        // No spatial split here: the references are large beside the node and cross most of its bins, so
        // chopped binning would cost the most per reference, for the least gain (docs/accel/bvh.md,
        // "Spatial splits": half the bunny's build time, for at most 0.5% of the SAH cost).
        SmallSubtree(refs_, max_leaf_, whole_leaf_size_, slots, range).build(slot, range, depth, bounds);
        // The subtree's leaves lie in its range's positions, its free ones included (its children share
        // them): all are recorded, those of no leaf never read.
        record_leaf_primitives(range.begin, range.capacity_end);
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
        set_leaf(slots, slot, bounds, range);
        return;
    }
    std::optional<Children> children;
    if (spatial_is_better) children = spatial_partition(range, bounds, spatial);
    if (!children) children = object_partition(range, object, map, centroids);
    const auto [first, second] = slots.set_inner(slot, bounds, children->axis);
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

void BinnedBuilder::set_leaf(NodeSlots& slots, std::size_t slot, const Box3f& bounds, const RefRange& range) {
    slots.set_leaf(slot, bounds, range.begin, range.size());
    record_leaf_primitives(range.begin, range.end);
}

void BinnedBuilder::record_leaf_primitives(std::size_t begin, std::size_t end) {
    for (std::size_t position = begin; position < end; ++position)
        per_position_[position] = refs_[position].prim;
}

// The object split's children: the binned partition, or an object median when nothing separates the
// centroids.
BinnedBuilder::Children BinnedBuilder::object_partition(const RefRange& range, const ObjectSplit& object,
                                                        const BinMap& map, const Box3f& centroids) {
    const std::size_t begin = range.begin, end = range.end, count = range.size();
    Split split = object.split;
    Children children;
    std::size_t middle;
    if (split.axis >= 0) {
        std::tie(middle, children.left_bounds.second, children.right_bounds.second) =
            partition(begin, end, map, split);
        children.left_bounds.first = object.left_bounds, children.right_bounds.first = object.right_bounds;
    } else {
        split = {max_axis(centroids.extent()), 0.0f, count / 2, 0};
        const int median_axis = split.axis;
        std::nth_element(
            refs_.begin() + static_cast<std::ptrdiff_t>(begin),
            refs_.begin() + static_cast<std::ptrdiff_t>(begin + split.left_count),
            refs_.begin() + static_cast<std::ptrdiff_t>(end),
            [median_axis](const BuildRef& a, const BuildRef& b) { return centroid_less(a, b, median_axis); });
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

BvhBuildResult build_binned_sah(BuildRefs& refs, std::size_t primitives, const Geometry& geometry,
                                const BvhOptions& options, std::size_t whole_leaf_size) {
    NodeSlots slots(refs.size());
    BinnedBuilder builder(refs, geometry, options, whole_leaf_size);
    builder.build(slots, primitives);
    return slots.compact([&](std::size_t i) { return builder.leaf_primitive(i); });
}

}  // namespace lancer
