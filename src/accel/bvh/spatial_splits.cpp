// The binned builder's spatial splits (Stich, Friedrich & Dietrich, "Spatial Splits in Bounding Volume
// Hierarchies", HPG 2009): chopped binning of a node's references between planes of its box, the cheapest
// plane, and the partition that cuts references in two (docs/accel/bvh.md, "Spatial splits").
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <tuple>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/bin_box.hpp"
#include "accel/bvh/binned_builder.hpp"
#include "core/parallel.hpp"

namespace lancer {
namespace {

// Planes tried per axis by a spatial split, as Embree's SBVH builder (HeuristicArraySpatialSAH).
constexpr int kSpatialBins = 16;

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

void spatial_bin_reference(const Geometry& geometry, const BuildRef& ref, const SpatialBinMap& map,
                           SpatialBins& bins) {
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
        if (!chopped) chopped.emplace(geometry, ref);
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

// Fills `bins` (made empty by the caller) from refs[begin, end): an out parameter, for the reason
// BinnedBuilder::bin gives.
void spatial_bin(const Geometry& geometry, std::span<const BuildRef> refs, std::size_t begin, std::size_t end,
                 const SpatialBinMap& map, SpatialBins& bins) {
    auto fill = [&](std::size_t from, std::size_t to, SpatialBins& into) {
        for (std::size_t i = from; i < to; ++i)
            spatial_bin_reference(geometry, refs[i], map, into);
    };
    if (end - begin > BinnedBuilder::kParallelBinning) {
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

// The reference with the bounds of its part on one side of a plane.
[[nodiscard]] BuildRef with_bounds(const BuildRef& ref, const Box3f& bounds) {
    return {bounds, bounds.center(), ref.prim};
}

}  // namespace

// Tried only where the node has free positions for the parts of the references it would cut, and where
// the best object split's children overlap by more than alpha times the root's area (Stich et al.,
// "restricting spatial split attempts": below that, a spatial split can gain little) and by a tenth of
// the node's area.
bool BinnedBuilder::worth_a_spatial_split(const RefRange& range, const Box3f& bounds,
                                          const ObjectSplit& object) const {
    if (!spatial_splits_ || range.free() == 0 || object.split.axis < 0) return false;
    const float overlap = intersection(object.left_bounds, object.right_bounds).surface_area();
    return overlap > min_overlap_area_ && overlap >= kMinNodeOverlap * bounds.surface_area();
}

// The cheapest plane of the node's spatial bins: the left child holds every reference that enters left
// of it, the right child every one that leaves right of it, the cut ones in both.
BinnedBuilder::SpatialSplit BinnedBuilder::best_spatial_split(const RefRange& range,
                                                              const Box3f& bounds) const {
    const SpatialBinMap map(bounds);
    SpatialBins bins;
    spatial_bin(geometry_, refs_, range.begin, range.end, map, bins);
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
std::optional<BinnedBuilder::Children> BinnedBuilder::spatial_partition(const RefRange& range,
                                                                        const Box3f& bounds,
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
    std::copy(right.begin(), right.end(), refs_.begin() + static_cast<std::ptrdiff_t>(children.right.begin));
    children.left_bounds = bounds_of(children.left.begin, children.left.end);
    children.right_bounds = bounds_of(children.right.begin, children.right.end);
    return children;
}

}  // namespace lancer
