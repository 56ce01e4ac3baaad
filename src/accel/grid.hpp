// Regular grid (the "Lancer de rayon" slides, "Grille régulière"): the scene box cut into about density^3 * N
// cubic cells, each listing the primitives that overlap it, walked front to back by the 3D-DDA of Amanatides
// & Woo, "A Fast Voxel Traversal Algorithm for Ray Tracing" (Eurographics 1987; the "Lancer de rayon" slides,
// "3DDDA"). Design note: docs/accel/grid.md.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "accel/options.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/single_ray.hpp"

namespace lancer {

// The options of `grid` (the "Lancer de rayon" slides): cells per axis = density * cbrt(N), shared among the
// axes in proportion to the box's extents, so that cells are about cubic.
struct GridOptions {
    static constexpr std::string_view kGroup = "grid";
    float density = 1.0f;
};

class GridAccel final : public SingleRayAccel<GridAccel> {
  public:
    // The `--set` keys of this structure's option group (accel/options.hpp).
    [[nodiscard]] static std::vector<BuildOptionRow> option_rows();
    // One cell's slice of the reference array: references_[cell_begin_[c]] .. references_[cell_begin_[c+1]].
    // 4 bytes per cell, plus 4 bytes per reference: a compressed-row (CSR) layout, no per-cell vector.
    using CellOffset = std::uint32_t;
    static_assert(sizeof(CellOffset) == 4);

    [[nodiscard]] std::string_view name() const override { return "grid"; }
    [[nodiscard]] AccelStats stats() const override;
    [[nodiscard]] std::size_t memory_bytes() const override;

    // The resolution rule: about density^3 * N cells, cubic, shared among the axes in proportion to the box's
    // extents (an axis too thin for one such cell gets exactly one), at most 64 N + 64 cells in all.
    [[nodiscard]] static std::array<int, 3> choose_resolution(const Box3f& bounds,
                                                              std::size_t primitive_count, float density);

    // The most references a build keeps: 64 N + 65536 (and what 32-bit offsets can address). A grid that
    // would need more is coarsened.
    [[nodiscard]] static std::size_t max_references(std::size_t primitive_count);

    // Inspection, for tests and tools. Cells are indexed (x, y, z), each in [0, resolution()[axis]).
    [[nodiscard]] std::array<int, 3> resolution() const { return resolution_; }
    [[nodiscard]] const Box3f& bounds() const { return bounds_; }
    // The cell between its planes, and that box grown by the geometric tolerance (build_util.hpp): the box a
    // primitive must overlap (primitive_overlaps_box) to be listed in the cell.
    [[nodiscard]] Box3f cell_box(int x, int y, int z) const;
    [[nodiscard]] Box3f reference_box(int x, int y, int z) const;
    [[nodiscard]] std::span<const std::uint32_t> cell_primitives(int x, int y, int z) const;

  private:
    friend SingleRayAccel<GridAccel>;

    void build_from(const Geometry& geometry, const BuildOptions& options);
    // Walks the cells the ray crosses (SingleRayAccel's contract).
    template <bool kAnyHit, bool kCount, class TriangleTestT>
    bool trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counters) const;

    // Fills cell_begin_ and references_ at the current resolution; false (and nothing kept) when the
    // references would exceed `reference_budget`.
    bool fill_cells(std::size_t reference_budget);
    void set_resolution(const std::array<int, 3>& resolution);
    // Coordinate of the plane between cells index - 1 and index on `axis` (0: the entry box's lower face,
    // resolution: its upper face). Build (cell boxes) and traversal (exit distances) read this one table, so
    // that a cell's box and the distances at which the walk enters and leaves it refer to the same planes,
    // bit for bit.
    [[nodiscard]] float plane(int axis, int index) const {
        return planes_[axis][static_cast<std::size_t>(index)];
    }
    // The cell holding coordinate x on `axis`, clamped to the grid (NaN goes to 0).
    [[nodiscard]] int cell_index(int axis, float x) const;
    [[nodiscard]] std::vector<std::pair<std::string, std::size_t>> memory_by_array() const;
    [[nodiscard]] std::size_t cell_count() const { return cell_begin_.empty() ? 0 : cell_begin_.size() - 1; }

    Box3f bounds_;            // the scene's box: its cells' size and index mapping derive from it
    float tolerance_ = 0.0f;  // geometric_tolerance(bounds_): cells and the entry box are grown by it
    Box3f entry_box_;         // bounds_ grown by tolerance_: the ray's entry (slab test) and the outer planes
    // Per-axis frame of the grid (arrays rather than Vec3f: the walk indexes them by a run-time axis).
    std::array<int, 3> resolution_{0, 0, 0};
    std::array<float, 3> lower_{}, cell_size_{}, inverse_cell_size_{};
    std::array<std::vector<float>, 3> planes_;  // resolution + 1 plane coordinates per axis
    std::vector<CellOffset> cell_begin_;        // cell count + 1 offsets into references_
    std::vector<std::uint32_t> references_;     // primitive indices, ascending within each cell
};

extern template class SingleRayAccel<GridAccel>;

}  // namespace lancer
