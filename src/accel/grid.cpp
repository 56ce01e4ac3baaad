#include "accel/grid.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "accel/build_util.hpp"
#include "accel/kdtree_build.hpp"
#include "accel/tree_shape.hpp"
#include "core/parallel.hpp"

namespace lancer {
namespace {

// Primitives per task of the parallel cell filling: a fixed block, so that the pairs' order (and the grid)
// does not depend on the thread count.
constexpr std::size_t kPairBlock = 8192;

// Cubic cells of side s with prod_a max(1, extent_a / s) ~= target_cells (the "Lancer de rayon" slides:
// resolution ~ cbrt(n) per axis for a cube). An axis thinner than s gets one cell and leaves the budget to
// the others, so a flat box is cut in its plane only. The rounded counts may overshoot max_cells: s then
// grows until they fit.
std::array<int, 3> resolution_for(const Box3f& bounds, double target_cells, double max_cells) {
    const Vec3f box_extent = bounds.extent();
    const std::array<double, 3> extent = {box_extent.x, box_extent.y, box_extent.z};
    std::array<bool, 3> single_cell{};
    for (int axis = 0; axis < 3; ++axis)
        single_cell[axis] = !(extent[axis] > 0.0 && std::isfinite(extent[axis]));
    double side = 0.0;
    bool thinned = true;
    while (thinned) {  // each pass sets at least one more axis to a single cell, or ends
        double volume = 1.0;
        int axes = 0;
        for (int axis = 0; axis < 3; ++axis) {
            if (!single_cell[axis]) volume *= extent[axis], ++axes;
        }
        if (axes == 0) break;
        side = std::pow(volume / target_cells, 1.0 / axes);
        thinned = false;
        for (int axis = 0; axis < 3; ++axis) {
            if (!single_cell[axis] && extent[axis] < side) single_cell[axis] = true, thinned = true;
        }
    }
    std::array<int, 3> resolution{1, 1, 1};
    while (true) {
        double cells = 1.0;
        for (int axis = 0; axis < 3; ++axis) {
            const double count = single_cell[axis] ? 1.0 : std::round(extent[axis] / side);
            resolution[axis] = static_cast<int>(std::clamp(count, 1.0, max_cells));
            cells *= resolution[axis];
        }
        if (cells <= max_cells || !(side > 0.0)) return resolution;
        side *= 1.01;
    }
}

// Linear cell indices are 32-bit while building (CellReference::cell).
constexpr double kMaxCells = static_cast<double>(std::numeric_limits<std::int32_t>::max());

double cell_cap(std::size_t primitive_count) {
    return std::min(64.0 * static_cast<double>(primitive_count) + 64.0, kMaxCells);
}

// The exit distance t = (plane - origin) * (1 / direction) of a cell carries a relative error of at most
// gamma(3): the subtraction of two floats, the reciprocal and the product are each rounded once (pbrt-v4,
// section 6.8). The walk stops only when the best hit lies before the smallest value the exact exit can take,
// so that a hit a rounding error past the cell's far face never ends the walk before the next cell is tested.
float exit_lower_bound(float t_exit) {
    constexpr float shrink = 2.0f * gamma_bound(3);
    return t_exit * (t_exit > 0.0f ? 1.0f - shrink : 1.0f + shrink);
}

}  // namespace

std::array<int, 3> GridAccel::choose_resolution(const Box3f& bounds, std::size_t primitive_count,
                                                float density) {
    if (!(density > 0.0f) || !std::isfinite(density))
        throw std::invalid_argument("grid: GridOptions::density must be positive and finite");
    if (primitive_count == 0 || bounds.empty()) return {0, 0, 0};
    const double max_cells = cell_cap(primitive_count);
    const double target = std::pow(static_cast<double>(density), 3.0) * static_cast<double>(primitive_count);
    return resolution_for(bounds, std::clamp(target, 1.0, max_cells), max_cells);
}

std::size_t GridAccel::max_references(std::size_t primitive_count) {
    const double budget = 64.0 * static_cast<double>(primitive_count) + 65536.0;
    return static_cast<std::size_t>(
        std::min(budget, static_cast<double>(std::numeric_limits<CellOffset>::max())));
}

void GridAccel::build_from(const Geometry& geometry, const BuildOptions& options) {
    bounds_ = geometry.bounds();
    // Kernels report hit points a few ulps off their primitive (docs/numerical-contract.md, "Boxes"): the
    // entry box and every cell are grown by the scene's geometric tolerance, so that neither the slab test
    // nor a cell's reference list culls a hit that brute force finds.
    tolerance_ = geometric_tolerance(bounds_);
    entry_box_ = bounds_.grown(tolerance_);
    cell_begin_.clear();
    references_.clear();
    const std::size_t primitive_count = geometry.size();
    if (primitive_count > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        throw std::length_error("grid: more primitives than Hit::prim can number");
    set_resolution(choose_resolution(bounds_, primitive_count, options.group<GridOptions>().density));
    if (resolution_[0] > 0) {
        // Bounded memory: large primitives each crossing a whole slice of cells would multiply the
        // references; the grid is then coarsened, 4 times fewer cells per try. One cell always fits.
        while (!fill_cells(max_references(primitive_count))) {
            const double cells = static_cast<double>(resolution_[0]) * resolution_[1] * resolution_[2];
            std::array<int, 3> coarser =
                resolution_for(bounds_, std::max(cells / 4.0, 1.0), cell_cap(primitive_count));
            if (static_cast<double>(coarser[0]) * coarser[1] * coarser[2] >= cells) coarser = {1, 1, 1};
            set_resolution(coarser);
        }
    }
}

void GridAccel::set_resolution(const std::array<int, 3>& resolution) {
    resolution_ = resolution;
    for (int axis = 0; axis < 3; ++axis) {
        lower_[axis] = bounds_.lo[axis];
        const float extent = bounds_.hi[axis] - lower_[axis];
        const float count = static_cast<float>(resolution[axis]);
        cell_size_[axis] = resolution[axis] > 0 ? extent / count : 0.0f;
        inverse_cell_size_[axis] = extent > 0.0f ? count / extent : 0.0f;
        // The outer planes are the entry box's faces, not the scene box's: the boundary cells reach as far as
        // the entry box, so that a ray that enters the grown box, or runs along a face of the scene box
        // inside the tolerance band, walks the cells there rather than leaving the grid at the scene box's
        // face (docs/numerical-contract.md, "Boxes").
        std::vector<float>& planes = planes_[axis];
        planes.assign(static_cast<std::size_t>(resolution[axis]) + 1, entry_box_.hi[axis]);
        planes[0] = entry_box_.lo[axis];
        for (int index = 1; index < resolution[axis]; ++index)
            planes[static_cast<std::size_t>(index)] =
                lower_[axis] + static_cast<float>(index) * cell_size_[axis];
    }
}

int GridAccel::cell_index(int axis, float x) const {
    const float cell = (x - lower_[axis]) * inverse_cell_size_[axis];
    if (!(cell >= 0.0f)) return 0;
    const int last = resolution_[axis] - 1;
    return cell >= static_cast<float>(last) ? last : static_cast<int>(cell);
}

bool GridAccel::fill_cells(std::size_t reference_budget) {
    // 8 bytes per (cell, primitive) pair while building; sorted by cell into the CSR arrays at the end.
    struct CellReference {
        std::uint32_t cell, prim;
    };
    // The tolerance plus twice the margin by which primitive_overlaps_box grows any reference box
    // (grown_for_overlap), so that the candidate cells taken from a primitive's bounds include every cell the
    // overlap test can accept, whatever the rounding of the coordinate-to-index mapping.
    std::array<float, 3> margin{};
    for (int axis = 0; axis < 3; ++axis) {
        const float magnitude = std::max(std::fabs(bounds_.lo[axis]), std::fabs(bounds_.hi[axis]));
        margin[axis] = tolerance_ + 2e-6f * (cell_size_[axis] + magnitude + 3.0f * tolerance_) + 1e-30f;
    }
    // The pairs of primitives [begin, end), in primitive order; false past the budget.
    auto list_pairs = [&](std::uint32_t begin, std::uint32_t end, std::vector<CellReference>& pairs) {
        for (std::uint32_t prim = begin; prim < end; ++prim) {
            const Box3f prim_bounds = primitive_bounds(geometry_, prim);
            std::array<int, 3> first{}, last{};
            for (int axis = 0; axis < 3; ++axis) {
                first[axis] = cell_index(axis, prim_bounds.lo[axis] - margin[axis]);
                last[axis] = cell_index(axis, prim_bounds.hi[axis] + margin[axis]);
            }
            // The "Lancer de rayon" slides: "une cellule : liste des objets l'intersectant" — the exact
            // overlap, not the bounds.
            for (int z = first[2]; z <= last[2]; ++z) {
                for (int y = first[1]; y <= last[1]; ++y) {
                    for (int x = first[0]; x <= last[0]; ++x) {
                        if (!primitive_overlaps_box(geometry_, prim, reference_box(x, y, z))) continue;
                        if (pairs.size() == reference_budget) return false;
                        const auto cell = static_cast<std::uint32_t>(
                            x + resolution_[0] * (y + static_cast<std::int64_t>(resolution_[1]) * z));
                        pairs.push_back({cell, prim});
                    }
                }
            }
        }
        return true;
    };
    const auto prim_count = static_cast<std::uint32_t>(geometry_.size());
    std::vector<CellReference> pairs;
    // Fixed blocks of primitives, each listing its pairs in primitive order, concatenated in block order:
    // the pairs the serial loop lists, whatever the thread count.
    const std::size_t block_count = (prim_count + kPairBlock - 1) / kPairBlock;
    std::vector<std::vector<CellReference>> blocks(block_count);
    std::atomic<bool> over_budget = false;
    parallel::for_each_index(0, block_count, [&](std::size_t block) {
        if (over_budget) return;
        const auto begin = static_cast<std::uint32_t>(block * kPairBlock);
        const auto end = static_cast<std::uint32_t>(std::min<std::size_t>(prim_count, begin + kPairBlock));
        if (!list_pairs(begin, end, blocks[block])) over_budget = true;
    });
    std::size_t total = 0;
    for (const std::vector<CellReference>& block : blocks)
        total += block.size();
    if (over_budget || total > reference_budget) return false;
    pairs.reserve(total);
    for (std::vector<CellReference>& block : blocks) {
        pairs.insert(pairs.end(), block.begin(), block.end());
        std::vector<CellReference>().swap(block);
    }
    // Counting sort by cell; stable, so each cell lists its primitives in ascending order (deterministic).
    const std::size_t cells = static_cast<std::size_t>(resolution_[0]) * resolution_[1] * resolution_[2];
    cell_begin_.assign(cells + 1, 0);
    for (const CellReference& pair : pairs)
        ++cell_begin_[pair.cell + 1];
    for (std::size_t cell = 0; cell < cells; ++cell)
        cell_begin_[cell + 1] += cell_begin_[cell];
    std::vector<CellOffset> cursor(cell_begin_.begin(), cell_begin_.end() - 1);
    references_.resize(pairs.size());
    for (const CellReference& pair : pairs)
        references_[cursor[pair.cell]++] = pair.prim;
    return true;
}

Box3f GridAccel::cell_box(int x, int y, int z) const {
    return {{plane(0, x), plane(1, y), plane(2, z)}, {plane(0, x + 1), plane(1, y + 1), plane(2, z + 1)}};
}

Box3f GridAccel::reference_box(int x, int y, int z) const {
    const Box3f box = cell_box(x, y, z);
    return box.grown(tolerance_);
}

std::span<const std::uint32_t> GridAccel::cell_primitives(int x, int y, int z) const {
    const std::size_t cell =
        static_cast<std::size_t>(x) +
        static_cast<std::size_t>(resolution_[0]) * (y + static_cast<std::size_t>(resolution_[1]) * z);
    return std::span(references_).subspan(cell_begin_[cell], cell_begin_[cell + 1] - cell_begin_[cell]);
}

// The 3D-DDA of Amanatides & Woo (1987; the "Lancer de rayon" slides, "Choisir la cellule suivante"), with
// the distances to the next plane on each axis recomputed from the planes themselves rather than accumulated
// (t_next += dt), so that each carries one bounded rounding error instead of one per step.
template <bool kAnyHit, bool kCount, class TriangleTestT>
bool GridAccel::trace(const PreparedRay<TriangleTestT>& prepared, Hit& best,
                      TraversalCounters& counters) const {
    const Ray& ray = prepared.ray;
    const SlabRay slab(ray);
    float t_entry, t_exit;
    if (cell_begin_.empty() || !intersect_box(slab, entry_box_, ray.tnear, ray.tfar, t_entry, t_exit))
        return false;

    // ENTRY: the cell of the entry point, which is the origin itself when it lies inside the box (t_entry is
    // then tnear; the "Lancer de rayon" slides: "l'origine du rayon peut être dans la boîte"). Clamping keeps
    // a rounded entry point that falls just outside the box in its boundary cell.
    const std::array<float, 3> origin = {ray.origin.x, ray.origin.y, ray.origin.z};
    const std::array<float, 3> inverse_direction = {slab.inv_direction.x, slab.inv_direction.y,
                                                    slab.inv_direction.z};
    const std::array<std::ptrdiff_t, 3> stride = {
        1, resolution_[0], static_cast<std::ptrdiff_t>(resolution_[0]) * resolution_[1]};
    std::array<int, 3> cell{}, past_last{};  // past_last: the index that leaves the grid
    std::array<std::ptrdiff_t, 3> linear_step{};
    std::array<const float*, 3> exit_planes{};  // exit_planes[axis][i]: the plane cell i leaves through
    std::array<float, 3> t_next{};
    for (int axis = 0; axis < 3; ++axis) {
        cell[axis] = cell_index(axis, origin[axis] + t_entry * ray.direction[axis]);
        if (!std::isfinite(inverse_direction[axis])) {
            // A zero (or denormal: 1 / d overflows) component: the ray never crosses a plane of this axis.
            t_next[axis] = kInfinity;
        } else {
            const bool forward = inverse_direction[axis] > 0.0f;
            past_last[axis] = forward ? resolution_[axis] : -1;
            linear_step[axis] = forward ? stride[axis] : -stride[axis];
            exit_planes[axis] = planes_[axis].data() + (forward ? 1 : 0);
            t_next[axis] = (exit_planes[axis][cell[axis]] - origin[axis]) * inverse_direction[axis];
        }
    }
    std::ptrdiff_t linear = cell[0] + stride[1] * cell[1] + stride[2] * cell[2];

    while (true) {
        // CELL: every primitive of the cell, within [tnear, best.t] (not clipped to the cell: a hit found
        // here that lies in a later cell stays the current best while the walk goes on).
        if constexpr (kCount) ++counters.nodes_visited;
        const CellOffset end = cell_begin_[static_cast<std::size_t>(linear) + 1];
        for (CellOffset reference = cell_begin_[static_cast<std::size_t>(linear)]; reference < end;
             ++reference) {
            if constexpr (kCount) ++counters.prims_tested;
            if constexpr (kAnyHit) {
                if (occludes(geometry_, references_[reference], prepared)) return true;
            } else {
                intersect_primitive(geometry_, references_[reference], prepared, best);
            }
        }
        // EXIT-FACE: the nearest next plane; ties go to the lower axis (deterministic).
        const int axis =
            t_next[0] <= t_next[1] ? (t_next[0] <= t_next[2] ? 0 : 2) : (t_next[1] <= t_next[2] ? 1 : 2);
        // The "Lancer de rayon" slides, "Intersection(s) dans la cellule ? Oui : retourner la plus proche":
        // stop once the best hit (or the end of the ray) lies inside the cells walked so far. An infinite
        // exit (no axis steps) stops too, since tfar <= +inf.
        const float limit = kAnyHit ? ray.tfar : std::min(best.t, ray.tfar);  // best.t is +inf on a miss
        if (limit <= exit_lower_bound(t_next[axis])) break;
        // NEIGHBOR
        cell[axis] += linear_step[axis] > 0 ? 1 : -1;
        if (cell[axis] == past_last[axis]) break;
        linear += linear_step[axis];
        t_next[axis] = (exit_planes[axis][cell[axis]] - origin[axis]) * inverse_direction[axis];
    }
    return !kAnyHit && best.hit();
}

template class SingleRayAccel<GridAccel>;

std::vector<std::pair<std::string, std::size_t>> GridAccel::memory_by_array() const {
    const std::size_t plane_count =
        cell_count() > 0 ? planes_[0].size() + planes_[1].size() + planes_[2].size() : 0;
    return {{"cell_begin", cell_begin_.size() * sizeof(CellOffset)},
            {"references", references_.size() * sizeof(std::uint32_t)},
            {"planes", plane_count * sizeof(float)}};
}

std::size_t GridAccel::memory_bytes() const {
    std::size_t bytes = 0;
    for (const auto& [name, array_bytes] : memory_by_array())
        bytes += array_bytes;
    return bytes;
}

AccelStats GridAccel::stats() const {
    AccelStats stats;
    stats.build_ms = build_ms_;
    stats.primitives = geometry_.size();
    const std::size_t cells = cell_count();
    std::size_t empty_cells = 0, max_refs = 0;
    for (std::size_t cell = 0; cell < cells; ++cell) {
        const std::size_t count = cell_begin_[cell + 1] - cell_begin_[cell];
        if (count == 0) ++empty_cells;
        max_refs = std::max(max_refs, count);
    }
    // Over non-empty cells: what a ray pays in a cell where it has anything to test.
    const std::size_t full_cells = cells - empty_cells;
    const double mean_refs =
        full_cells > 0 ? static_cast<double>(references_.size()) / static_cast<double>(full_cells) : 0.0;
    // SAH cost of the grid seen as a one-level tree (MacDonald & Booth 1990): a ray crossing the box enters
    // cell c with probability SA(c) / SA(box), then steps once and tests its references:
    //   C = sum_c SA(c) / SA(box) (C_step + C_isect n_c) = SA(cell) / SA(box) (C_step cells + C_isect refs),
    // with the kd-tree's default constants (C_step = traversal_cost 15, C_isect = intersection_cost 20) so
    // that the two figures compare. 0 when the box has no area (a segment or a point).
    const double box_area = bounds_.surface_area();
    double sah_cost = 0.0;
    if (cells > 0 && box_area > 0.0) {
        const KdTreeOptions constants;
        const double cx = cell_size_[0], cy = cell_size_[1], cz = cell_size_[2];
        const double cell_area = 2.0 * (cx * cy + cy * cz + cz * cx);
        sah_cost = cell_area / box_area *
                   (constants.traversal_cost * static_cast<double>(cells) +
                    constants.intersection_cost * static_cast<double>(references_.size()));
    }
    stats.figures = {
        count_figure("cells", cells, "cells of the grid"),
        count_figure("empty_cells", empty_cells, "cells that hold no primitive"),
        count_figure("references", references_.size(),
                     "primitive references in the cells, duplicates included"),
        value_figure("mean_refs_per_cell", mean_refs, "mean references of the cells that hold any"),
        count_figure("max_refs_per_cell", max_refs, "most references in one cell"),
        value_figure("sah_cost", sah_cost,
                     "the grid as a one-level tree (MacDonald & Booth), the kd-tree's step and test costs")};
    stats.memory_by_array = memory_by_array();
    return stats;
}

std::vector<BuildOptionRow> GridAccel::option_rows() {
    return {number_option("density", "the cube root of the cells per primitive", &GridOptions::density, 0.01f,
                          64.0f)};
}

}  // namespace lancer
