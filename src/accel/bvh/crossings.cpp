// GeometryQueries::count_crossings (lancer/queries.hpp): how many times rays along one direction cross the
// surface, from a grid of the triangles seen along that direction (accel/crossing_grid.hpp) where the rays
// are many, from walks of the tree otherwise. docs/python.md, "Occupancy", has the steps and their measures.
#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "accel/bvh/queries_impl.hpp"
#include "accel/bvh/triangle_block.hpp"
#include "accel/primitive_intersect.hpp"
#include "core/host_device.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/parallel.hpp"

namespace lancer {

namespace {

using queries_detail::CrossingBuffers;
using queries_detail::distinct_count;
using queries_detail::RayInCell;

// The radix sort's digits: at most 2^11 values, so that the counts and the places they scatter to stay in
// the first-level cache.
constexpr int kMaxDigitBits = 11;

}  // namespace

void GeometryQueries::count_crossings(const Vec3f& direction, std::span<const Vec3f> origins,
                                      std::span<std::uint32_t> crossings, int threads) const {
    const Accel& scene = *impl_->scene;
    const Geometry& geometry = scene.built_geometry();
    const std::size_t count = origins.size();
    constexpr std::size_t kRaysPerTask = 1024;
    // The rays share their direction and interval [0, inf]: a direction that leaves them invalid hits
    // nothing.
    if (geometry.size() == 0 || !is_valid(Ray{Vec3f(0.0f), direction, 0.0f, kInfinity})) {
        std::fill_n(crossings.begin(), count, 0u);
        return;
    }
    // The grid costs a pass over the triangles and their cells; a ray through it a few block tests, where a
    // tree walk costs several times that: it pays from about one ray per four primitives. A scene scaled to
    // the structures' range (Accel::scale_exponent), or a direction scaled to the kernels' (a component
    // beyond [2^-32, 2^32]), conditions every ray: those walk the tree. Cells are numbered below 2^32 - 1 (at
    // most about 1.5 a primitive, and primitives below 2^31).
    const FarOriginFrame frame(scene.bounds());
    if (scene.scale_exponent() != 0 || 4 * count < geometry.size() ||
        count > std::numeric_limits<std::uint32_t>::max() ||
        may_need_conditioning(Ray{frame.centre(), direction, 0.0f, kInfinity}, frame)) {
        parallel_for(count, kRaysPerTask, threads, [&](std::size_t first, std::size_t last) {
            std::vector<float> task_times;
            for (std::size_t i = first; i < last; ++i) {
                const Ray ray{origins[i], direction, 0.0f, kInfinity};
                crossings[i] = is_finite(ray.origin) ? impl_->walked_crossings(ray, task_times) : 0u;
            }
        });
        return;
    }
    const std::shared_ptr<const CrossingGrid> grid = impl_->grids.grid(
        geometry, scene.built_bounds(), direction, geometry.size() / 2, threads, scene.geometry_version_);
    // The arrays of the last call, unless another thread's call holds them.
    std::unique_lock<std::mutex> buffers_lock(impl_->buffers_mutex, std::try_to_lock);
    CrossingBuffers own_buffers;
    CrossingBuffers& buffers = buffers_lock.owns_lock() ? impl_->buffers : own_buffers;

    // First pass, in kRuns runs of consecutive rays: the rays that test a cell's primitives are written out,
    // each run's from its own place on; the others get their answer now: a ray from a non-finite origin
    // (invalid) or one whose cell lists nothing crosses nothing, and one from far away, which conditioning
    // moves, walks the tree (the direction is valid and needs none: of a ray, only the origin is checked).
    // The cells' first digits are counted on the way for the radix sort.
    constexpr std::size_t kRuns = 4;
    const std::size_t run = std::max<std::size_t>((count + kRuns - 1) / kRuns, 1);
    const int cell_bits = static_cast<int>(std::bit_width(grid->cell_count() - 1));
    const int passes = std::max(1, (cell_bits + kMaxDigitBits - 1) / kMaxDigitBits);
    const int digit_bits = std::max(1, (cell_bits + passes - 1) / passes);
    const std::size_t digits = std::size_t{1} << digit_bits;
    const std::span<RayInCell> listed_rays = buffers.rays.first(count), sorted = buffers.sorted.first(count);
    const std::span<std::uint32_t> digit_counts = buffers.digit_counts.first(kRuns * passes * digits);
    std::fill(digit_counts.begin(), digit_counts.end(), 0u);
    std::array<std::size_t, kRuns> run_rays{};
    parallel_for(count, run, threads, [&](std::size_t first, std::size_t last) {
        const std::size_t r = first / run;
        std::uint32_t* counts = digit_counts.data() + r * passes * digits;
        std::size_t written = first;
        std::vector<float> task_times;
        const auto one = [&](std::size_t i) {
            const Vec3f& origin = origins[i];
            if (!is_finite(origin)) {
                crossings[i] = 0;
            } else if (frame.is_far(origin)) {
                crossings[i] = impl_->walked_crossings({origin, direction, 0.0f, kInfinity}, task_times);
            } else if (const std::size_t cell = grid->cell_of(origin); !grid->lists_any(cell)) {
                crossings[i] = 0;
            } else {
                listed_rays[written++] = {static_cast<std::uint32_t>(cell), static_cast<std::uint32_t>(i),
                                          origin};
                ++counts[cell & (digits - 1)];
            }
        };
        // Eight origins at a time where all are finite and near (the grid's vector cells), without a branch
        // on whether each is listed: every ray is written at the next place, which only a listed one keeps,
        // and every answer set to 0, which the listed ones' tests overwrite. Taken ray by ray, that branch
        // went either way at random (41% of the bunny's rays are listed) and mispredicted (docs/python.md,
        // "Occupancy").
        const Vec3f centre = frame.centre();
        const float limit = frame.far_limit();
        std::size_t i = first;
        for (; i + 8 <= last; i += 8) {
            std::array<std::uint32_t, 8> cells;
            const int listed = grid->listed_cells(&origins[i], centre, limit, cells.data());
            if (listed < 0) {
                for (std::size_t j = i; j < i + 8; ++j)
                    one(j);
                continue;
            }
            for (std::size_t j = 0; j < 8; ++j) {
                const std::uint32_t cell = cells[j], kept = (static_cast<unsigned>(listed) >> j) & 1u;
                crossings[i + j] = 0;
                listed_rays[written] = {cell, static_cast<std::uint32_t>(i + j), origins[i + j]};
                written += kept;
                counts[cell & (digits - 1)] += kept;
            }
        }
        for (; i < last; ++i)
            one(i);
        run_rays[r] = written - first;
    });
    // An LSD radix sort by cell, stable, so that a cell's rays stay in the order of their index. Each pass
    // in kRuns chunks on the threads, each chunk's rays scattered from its own places on, those of a digit
    // after the earlier chunks' (the first pass's chunks are the runs, whose digits it counted; a later
    // pass's are counted first): on one thread, the sort was a serial part of a call on two (docs/python.md,
    // "Occupancy").
    std::size_t listed = 0;
    for (const std::size_t n : run_rays)
        listed += n;
    std::span<RayInCell> from = listed_rays, to = sorted;
    std::array<std::size_t, kRuns> chunk_first{}, chunk_last{};
    for (std::size_t r = 0; r < kRuns; ++r)
        chunk_first[r] = r * run, chunk_last[r] = r * run + run_rays[r];
    std::vector<std::size_t> next(kRuns * digits);
    for (int pass = 0; pass < passes; ++pass) {
        const int shift = pass * digit_bits;
        const auto digit = [&](const RayInCell& ray) { return (ray.cell >> shift) & (digits - 1); };
        const auto counts_of = [&](std::size_t r) {
            return digit_counts.data() +
                   (r * static_cast<std::size_t>(passes) + static_cast<std::size_t>(pass)) * digits;
        };
        if (pass > 0) {
            const std::size_t chunk = (listed + kRuns - 1) / kRuns;
            for (std::size_t r = 0; r < kRuns; ++r)
                chunk_first[r] = std::min(r * chunk, listed),
                chunk_last[r] = std::min(r * chunk + chunk, listed);
            parallel_for(kRuns, 1, threads, [&](std::size_t first, std::size_t last) {
                for (std::size_t r = first; r < last; ++r) {
                    std::uint32_t* counts = counts_of(r);
                    for (std::size_t k = chunk_first[r]; k < chunk_last[r]; ++k)
                        ++counts[digit(from[k])];
                }
            });
        }
        std::size_t place = 0;
        for (std::size_t d = 0; d < digits; ++d) {
            for (std::size_t r = 0; r < kRuns; ++r)
                next[r * digits + d] = place, place += counts_of(r)[d];
        }
        parallel_for(kRuns, 1, threads, [&](std::size_t first, std::size_t last) {
            for (std::size_t r = first; r < last; ++r) {
                std::size_t* at = next.data() + r * digits;
                for (std::size_t k = chunk_first[r]; k < chunk_last[r]; ++k)
                    to[at[digit(from[k])]++] = from[k];
            }
        });
        std::swap(from, to);
    }
    const std::span<const RayInCell> by_cell = from.first(listed);
    const Geometry in_grid_order{grid->triangles(), geometry.spheres};
    // Cell by cell: its primitives gathered into blocks once for its rays (once per task that holds some of
    // them), each ray tested against them by bvh8's block kernel, the tree's own bits, its answer's place
    // prefetched a few rays ahead (each is a cache miss).
    constexpr std::size_t kPrefetchAhead = 8;
    constexpr auto kLanes = static_cast<std::size_t>(Bvh8Accel::kBlockLanes);
    parallel_for(listed, kRaysPerTask, threads, [&](std::size_t first, std::size_t last) {
        std::vector<float> task_times;
        std::vector<Bvh8Accel::Block> blocks;
        std::vector<double> block_far;  // the farthest depth of each of the cell's blocks
        std::size_t blocks_cell = std::numeric_limits<std::size_t>::max();
        dispatch_policies(impl_->test, false, [&]<class TriangleTestT, bool>() {
            // The ray prepared and broadcast once, its origin set for each: built per ray, its copies through
            // the stack stalled on store forwarding and its set-up's calls were not inlined (docs/python.md,
            // "Occupancy").
            PreparedRay<TriangleTestT> prepared(Ray{Vec3f(0.0f), direction, 0.0f, kInfinity});
            BlockRay<TriangleTestT, Bvh8Accel::kBlockLanes> block_ray(prepared, in_grid_order);
            for (std::size_t k = first; k < last; ++k) {
                if (k + kPrefetchAhead < listed) prefetch_line(&crossings[by_cell[k + kPrefetchAhead].index]);
                const RayInCell& ray = by_cell[k];
                const std::uint32_t cell = ray.cell, i = ray.index;
                const Vec3f origin = ray.origin();
                if (cell != blocks_cell) {
                    const std::span<const std::uint32_t> prims = grid->primitives(cell);
                    blocks.clear();
                    append_leaf_blocks(in_grid_order, prims, blocks);
                    block_far.clear();
                    for (std::size_t last_lane = kLanes - 1; last_lane < prims.size() + kLanes - 1;
                         last_lane += kLanes)
                        block_far.push_back(grid->far_depth(
                            in_grid_order.triangles[prims[std::min(last_lane, prims.size() - 1)]]));
                    append_leaf_blocks(in_grid_order, grid->every_ray(), blocks);
                    blocks_cell = cell;
                }
                prepared.set_origin(origin);
                block_ray.kernel.set_origin(origin);
                task_times.clear();
                // The cell's blocks wholly behind the origin skipped (their triangles by far depth).
                const double behind = grid->depth(origin) - grid->depth_slack();
                const auto first_block = static_cast<std::size_t>(
                    std::lower_bound(block_far.begin(), block_far.end(), behind) - block_far.begin());
                for (std::size_t b = first_block; b < blocks.size(); ++b) {
                    each_block_hit(in_grid_order, blocks[b], block_ray,
                                   [&](const Hit& hit) { task_times.push_back(hit.t); });
                }
                crossings[i] = distinct_count(task_times);
            }
        });
    });
    // Arrays for more rays than kKeptRays are dropped: kept, a call of 10^8 points would hold 4 GB after it.
    constexpr std::size_t kKeptRays = std::size_t{1} << 22;
    if (count > kKeptRays) buffers = CrossingBuffers{};
}

}  // namespace lancer
