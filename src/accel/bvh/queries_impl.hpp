// GeometryQueries' state (lancer/queries.hpp), shared by its two sources: queries.cpp (the trees' walks:
// all hits, nearest points) and crossings.cpp (count_crossings, the grid along a direction and its arrays).
// Private to them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <type_traits>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/crossing_grid.hpp"
#include "lancer/queries.hpp"

namespace lancer {
namespace queries_detail {

// An array reused from call to call: grown when too small, never shrunk nor cleared, so that a call no larger
// than an earlier one writes into pages already faulted in, which fresh ones cost more than the work on
// them (docs/python.md, "Occupancy").
template <class T>
class ReusedArray {
  public:
    [[nodiscard]] std::span<T> first(std::size_t count) {
        if (count > capacity_) data_ = std::make_unique_for_overwrite<T[]>(count), capacity_ = count;
        return {data_.get(), count};
    }

  private:
    std::unique_ptr<T[]> data_;
    std::size_t capacity_ = 0;
};

// The distinct values of `times`, which it sorts.
inline std::uint32_t distinct_count(std::vector<float>& times) {
    std::sort(times.begin(), times.end());
    return static_cast<std::uint32_t>(std::unique(times.begin(), times.end()) - times.begin());
}

// A ray of count_crossings that tests a cell's primitives: its cell, its index among the origins, and its
// origin, moved with it by the sort so that the rays of a cell read theirs in turn: read through the index,
// each origin is a TLB and cache miss, which prefetching did not hide (docs/python.md, "Occupancy").
// Its origin as three floats, not a Vec3f, whose member initialisers made make_unique_for_overwrite zero the
// arrays (40 bytes a point, at every first call; docs/python.md, "Occupancy").
struct RayInCell {
    std::uint32_t cell;
    std::uint32_t index;
    float x, y, z;

    RayInCell() = default;
    RayInCell(std::uint32_t c, std::uint32_t i, const Vec3f& o) : cell(c), index(i), x(o.x), y(o.y), z(o.z) {}
    [[nodiscard]] Vec3f origin() const { return {x, y, z}; }
};
static_assert(sizeof(RayInCell) == 20 && std::is_trivially_default_constructible_v<RayInCell>);

// count_crossings' arrays, kept between calls: the rays that test a cell's primitives, in their order and by
// cell (a radix sort's two arrays), and the counts of the cells' digits.
struct CrossingBuffers {
    ReusedArray<RayInCell> rays, sorted;
    ReusedArray<std::uint32_t> digit_counts;
};

}  // namespace queries_detail

// One tree is walked: the structure's own (binary, bvh4's or bvh8's), or `own`. Either was
// built on `scene`'s built geometry, which is the caller's scaled by 2^scale_exponent
// (Accel::built_geometry): rays and points are conditioned and scaled as Accel::intersect's are, and answers
// mapped back. The structure is read at each query, so that its updates are followed.
struct GeometryQueries::Impl {
    TriangleTest test = TriangleTest::MollerTrumbore;
    BvhAccel own;  // built only for a structure that has no BVH
    const Accel* scene = nullptr;
    const BvhAccel* binary = nullptr;
    const Bvh4Accel* bvh4 = nullptr;
    const Bvh8Accel* bvh8 = nullptr;
    bool walks_accel = false;

    // count_crossings' grids, and its arrays, kept between calls (docs/python.md, "Occupancy").
    CrossingGrids grids;
    std::mutex buffers_mutex;
    queries_detail::CrossingBuffers buffers;

    // on_hit(hit) for every hit of `traced`, a valid ray conditioned for `scene`, in no order.
    template <class OnHit>
    void each_hit(const Ray& traced, OnHit&& on_hit) const;
    // on_hit(hit) for every hit of `ray`, a valid ray as the caller gave it, in no order: conditioned and
    // walked as each_hit, each t mapped back to the caller's parametrisation as Accel::intersect maps its
    // hits (one beyond the float range is none).
    template <class OnHit>
    void each_caller_hit(const Ray& ray, OnHit&& on_hit) const;
    // The crossings of a valid ray (count_crossings) by a walk of the tree, its hits as all_hits gives them;
    // `times` is scratch.
    std::uint32_t walked_crossings(const Ray& ray, std::vector<float>& times) const;
};

}  // namespace lancer
