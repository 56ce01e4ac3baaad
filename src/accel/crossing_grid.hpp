// The triangles of a geometry seen along one direction: projected onto the plane across it and binned in a
// grid of square cells over that plane, so that a ray of that direction can hit only the triangles listed
// in its origin's cell. Occupancy casts every point's ray along the same few directions
// (GeometryQueries::count_crossings): one grid a direction serves all of them, and each ray tests its
// cell's triangles without a walk (docs/python.md, "Point queries").
//
// A cell lists every triangle whose shadow covers some of it: the bounding rectangle of its corners'
// projections, grown by the projection of a cube of side twice the scene's geometric tolerance, which holds
// every hit the triangle tests report (accel/build_util.hpp, docs/numerical-contract.md, "Boxes"), so that
// the line of every ray the triangle test says hits it projects inside. The projections are made in
// double, and each shadow grown by a bound of their rounding for every origin a cell is asked for (within
// kFarOriginSides sides of the scene's centre; farther ones are conditioned); the cell of a coordinate is
// monotone in it, so the origin's cell lies among the shadow's. Of the shadow's cells, those inside the
// grid that an edge of the projected triangle separates from the triangle, the cell grown as the shadow is
// (and by a bound of its own rounding), are dropped: no such hit projects there. Spheres and triangles with
// a non-finite corner are listed apart, for every ray.
//
// The grid holds its own copy of the triangles, in the order of their shadows' first cells, so that the
// triangles of neighbouring cells, which the rays visit in turn, lie together in memory.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "lancer/box.hpp"
#include "lancer/scene.hpp"
#include "lancer/vec.hpp"
#include "lancer/vec3d.hpp"

namespace lancer {

class CrossingGrid {
  public:
    // The grid of `geometry`, whose box is `bounds`, along `direction` (non-zero, finite), of about `cells`
    // cells (at least 1), made on `threads` threads as parallel_for takes them.
    CrossingGrid(const Geometry& geometry, const Box3f& bounds, const Vec3f& direction, std::size_t cells,
                 int threads);

    [[nodiscard]] const Vec3f& direction() const { return direction_; }
    [[nodiscard]] std::size_t cell_count() const { return first_.size() - 1; }
    // The cell of a ray from `origin` along the direction.
    [[nodiscard]] std::size_t cell_of(const Vec3f& origin) const {
        const Plane p = project(origin);
        return row(p.v) * columns_ + column(p.u);
    }
    // The cells of the eight origins from `origins` on, as cell_of gives them, into `cells`, and a bit for
    // each whose cell lists any primitive (lists_any), when every origin is finite and within `limit` of
    // `centre` on every axis (the difference in float, as FarOriginFrame::is_far); -1 otherwise, `cells`
    // left unspecified. With AVX2 the eight in vectors, each projection in the same double operations as
    // cell_of's, in the same order: the first pass over a call's points asks this of each (docs/python.md,
    // "Occupancy").
    [[nodiscard]] int listed_cells(const Vec3f* origins, const Vec3f& centre, float limit,
                                   std::uint32_t* cells) const;

    // The geometry's triangles in the grid's order, which primitives() and every_ray() number (a sphere s
    // as triangles().size() + s, as in the geometry): the same triangles, bit for bit, so that a ray's hits
    // on them have the geometry's t.
    [[nodiscard]] std::span<const Triangle> triangles() const { return triangles_; }
    // The primitives a ray in `cell` can hit, by increasing far_depth (ties by index), and every_ray's.
    [[nodiscard]] std::span<const std::uint32_t> primitives(std::size_t cell) const {
        return {prims_.data() + first_[cell], prims_.data() + first_[cell + 1]};
    }
    // The primitives no cell bounds: spheres, and triangles with a non-finite corner.
    [[nodiscard]] std::span<const std::uint32_t> every_ray() const { return every_ray_; }
    // The depth along the direction (the unit vector's dot product, in double) of a ray's origin, and the
    // farthest of a triangle's corners: a ray hits no triangle whose far_depth lies below its origin's
    // depth by more than depth_slack(), the reach of the geometric tolerance's cube along the direction and
    // the depths' rounding (t >= 0 puts every hit at or beyond the origin's depth). primitives(cell) are in
    // increasing far_depth.
    [[nodiscard]] double depth(const Vec3f& p) const { return dot(Vec3d(p), axis_w_); }
    [[nodiscard]] double far_depth(const Triangle& tri) const {
        return std::max({depth(tri.v0), depth(tri.v1), depth(tri.v2)});
    }
    [[nodiscard]] double depth_slack() const { return depth_slack_; }
    // Whether a ray in `cell` has any primitive to test.
    [[nodiscard]] bool lists_any(std::size_t cell) const {
        return ((listed_[cell / 64] >> (cell % 64)) & 1u) != 0 || !every_ray_.empty();
    }
    [[nodiscard]] std::size_t memory_bytes() const {
        return sizeof(*this) + triangles_.capacity() * sizeof(Triangle) +
               first_.capacity() * sizeof(std::size_t) +
               (prims_.capacity() + every_ray_.capacity()) * sizeof(std::uint32_t) +
               listed_.capacity() * sizeof(std::uint64_t);
    }

  private:
    struct Plane {
        double u, v;
    };
    [[nodiscard]] Plane project(const Vec3f& p) const {
        const Vec3d q(p);
        return {dot(q, axis_u_), dot(q, axis_v_)};
    }
    // floor((x - lo) / side) clamped to [0, last] (NaN, which no valid ray has, to 0): monotone in x. The
    // last cell given as a double and the result converted through a signed integer (exact: below 2^32),
    // which x86 does in one instruction each, where size_t takes a branch: every ray asks twice.
    [[nodiscard]] static std::size_t cell_along(double x, double lo, double cells_per_unit, double last) {
        const double cell = std::floor((x - lo) * cells_per_unit);
        return cell > 0.0 ? static_cast<std::size_t>(static_cast<std::int64_t>(std::min(cell, last))) : 0;
    }
    [[nodiscard]] std::size_t column(double u) const {
        return cell_along(u, lo_u_, cells_per_unit_, last_column_);
    }
    [[nodiscard]] std::size_t row(double v) const { return cell_along(v, lo_v_, cells_per_unit_, last_row_); }

    Vec3f direction_;
    Vec3d axis_u_{0, 0, 0}, axis_v_{0, 0, 0};  // unit vectors across the direction and each other
    Vec3d axis_w_{0, 0, 0};                    // the direction's unit vector
    double depth_slack_ = 0.0;
    double lo_u_ = 0.0, lo_v_ = 0.0;
    double cells_per_unit_ = 0.0;  // 1 / the cells' side
    std::size_t columns_ = 1, rows_ = 1;
    double last_column_ = 0.0, last_row_ = 0.0;  // columns_ - 1, rows_ - 1
    std::vector<Triangle> triangles_;
    std::vector<std::size_t> first_;  // cell c lists prims_[first_[c], first_[c + 1])
    std::vector<std::uint32_t> prims_;
    std::vector<std::uint32_t> every_ray_;
    // A bit a cell: whether it lists a primitive. Most rays ask only this (most cells list nothing or hold
    // no ray), and the bits of the dragon's grid stay in cache where its first_ (3.5 MB) did not.
    std::vector<std::uint64_t> listed_;
};

// The grids of one geometry along the directions last asked for, kept between calls: a grid depends only on
// the triangles and the direction, and occupancy asks for the same few directions at every call, whose rays
// cost less than the grid's build (docs/python.md, "Occupancy"). The grids kept take at
// most as many bytes as the geometry's triangles, the most recently used kept first, and the last one
// whatever its size. Safe to call from several threads: a grid is built outside the lock and shared
// read-only.
class CrossingGrids {
  public:
    // The grid of `geometry` (CrossingGrid's arguments) along `direction`: a kept one when `version`
    // numbers the geometry the kept ones were made for (those of another are dropped), else a new one, then
    // kept.
    [[nodiscard]] std::shared_ptr<const CrossingGrid> grid(const Geometry& geometry, const Box3f& bounds,
                                                           const Vec3f& direction, std::size_t cells,
                                                           int threads, std::uint64_t version);

  private:
    std::mutex mutex_;
    std::uint64_t version_ = 0;
    std::vector<std::shared_ptr<const CrossingGrid>> grids_;  // the most recently used last
};

}  // namespace lancer
