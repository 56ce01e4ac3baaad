#include "accel/crossing_grid.hpp"

#include <algorithm>
#include <limits>
#include <numeric>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

#include "accel/build_util.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/parallel.hpp"

namespace lancer {

CrossingGrid::CrossingGrid(const Geometry& geometry, const Box3f& bounds, const Vec3f& direction,
                           std::size_t cells, int threads)
    : direction_(direction) {
    // Two unit vectors across the direction: the cross product with the axis it is least along, then the
    // third side of the frame.
    const Vec3d d = normalize(Vec3d(direction));
    const Vec3d least = std::fabs(d.x) <= std::fabs(d.y) && std::fabs(d.x) <= std::fabs(d.z) ? Vec3d(1, 0, 0)
                        : std::fabs(d.y) <= std::fabs(d.z)                                   ? Vec3d(0, 1, 0)
                                                                                             : Vec3d(0, 0, 1);
    axis_u_ = normalize(cross(d, least));
    axis_v_ = cross(d, axis_u_);
    // A cube of half-side g projects onto an axis a as g (|a.x| + |a.y| + |a.z|) either way. The double
    // rounding of a projection is below 2^-50 of the coordinates it sums, the corners' and the origins'.
    const double tolerance = geometric_tolerance(bounds);
    const double reach = std::max(max_component(abs(bounds.lo)), max_component(abs(bounds.hi))) +
                         (kFarOriginSides + 1.0) * max_component(bounds.extent());
    const double rounding = 0x1p-40 * reach;
    const auto l1 = [](const Vec3d& a) { return std::fabs(a.x) + std::fabs(a.y) + std::fabs(a.z); };
    const double grow_u = tolerance * l1(axis_u_) + rounding, grow_v = tolerance * l1(axis_v_) + rounding;
    axis_w_ = d;
    depth_slack_ = tolerance * l1(d) + rounding;

    // Each triangle's shadow, made twice in parallel: for the shadows' union, which sizes the cells, then for
    // its cells. Kept in between, the shadows would be an array of 32 bytes a triangle, whose fresh pages
    // cost more than the projections.
    struct Shadow {
        double lo_u, hi_u, lo_v, hi_v;
        [[nodiscard]] bool finite() const {
            return std::isfinite(lo_u) && std::isfinite(hi_u) && std::isfinite(lo_v) && std::isfinite(hi_v);
        }
        void extend(const Shadow& s) {
            lo_u = std::min(lo_u, s.lo_u), hi_u = std::max(hi_u, s.hi_u);
            lo_v = std::min(lo_v, s.lo_v), hi_v = std::max(hi_v, s.hi_v);
        }
    };
    const auto shadow_of = [&](const Triangle& tri) {
        const Plane p0 = project(tri.v0), p1 = project(tri.v1), p2 = project(tri.v2);
        return Shadow{std::min({p0.u, p1.u, p2.u}) - grow_u, std::max({p0.u, p1.u, p2.u}) + grow_u,
                      std::min({p0.v, p1.v, p2.v}) - grow_v, std::max({p0.v, p1.v, p2.v}) + grow_v};
    };
    constexpr Shadow kNone{kInfinity, -kInfinity, kInfinity, -kInfinity};
    const std::size_t triangles = geometry.triangles.size();
    constexpr std::size_t kTrianglesPerTask = 16384;
    std::vector<Shadow> task_unions((triangles + kTrianglesPerTask - 1) / kTrianglesPerTask, kNone);
    parallel_for(triangles, kTrianglesPerTask, threads, [&](std::size_t first, std::size_t last) {
        Shadow& all = task_unions[first / kTrianglesPerTask];
        for (std::size_t i = first; i < last; ++i) {
            if (const Shadow s = shadow_of(geometry.triangles[i]); s.finite()) all.extend(s);
        }
    });
    Shadow all = kNone;
    for (const Shadow& task_union : task_unions)
        all.extend(task_union);
    // Square cells, about `cells` of them over the union of the shadows.
    cells = std::max<std::size_t>(cells, 1);
    if (all.lo_u <= all.hi_u) {
        lo_u_ = all.lo_u, lo_v_ = all.lo_v;
        const double width = all.hi_u - all.lo_u, height = all.hi_v - all.lo_v;
        const double side = std::sqrt(width * height / static_cast<double>(cells));
        if (side > 0.0) {
            cells_per_unit_ = 1.0 / side;
            columns_ = std::min(static_cast<std::size_t>(width * cells_per_unit_) + 1, cells + 1);
            rows_ = std::min(static_cast<std::size_t>(height * cells_per_unit_) + 1, cells + 1);
        }
    }
    last_column_ = static_cast<double>(columns_ - 1), last_row_ = static_cast<double>(rows_ - 1);
    // Each shadow's columns and rows, in parallel; then two passes: count each cell's triangles, list them.
    struct Span {
        std::uint32_t c0, c1, r0, r1;  // c1 < c0 for a triangle listed apart
    };
    std::vector<Span> spans(triangles);
    parallel_for(triangles, kTrianglesPerTask, threads, [&](std::size_t first, std::size_t last) {
        for (std::size_t i = first; i < last; ++i) {
            const Shadow s = shadow_of(geometry.triangles[i]);
            spans[i] = s.finite() ? Span{static_cast<std::uint32_t>(column(s.lo_u)),
                                         static_cast<std::uint32_t>(column(s.hi_u)),
                                         static_cast<std::uint32_t>(row(s.lo_v)),
                                         static_cast<std::uint32_t>(row(s.hi_v))}
                                  : Span{1, 0, 1, 0};
        }
    });
    // The triangles copied in the order of their shadow's first cell, row by row (those listed apart last),
    // so that the triangles of neighbouring cells lie together in memory: the rays go through the cells in
    // that order, and gathered from the geometry's order most of a cell's triangles were cache misses
    // (docs/python.md, "Occupancy"). A stable counting sort.
    const std::size_t cell_total = columns_ * rows_;
    const auto home = [&](const Span& span) {
        return span.c1 < span.c0 ? cell_total : std::size_t{span.r0} * columns_ + span.c0;
    };
    std::vector<std::uint32_t> by_home(cell_total + 2, 0);
    for (const Span& span : spans)
        ++by_home[home(span) + 1];
    std::inclusive_scan(by_home.begin(), by_home.end(), by_home.begin());
    std::vector<std::uint32_t> order(triangles);  // the original index of each copied triangle
    for (std::size_t i = 0; i < triangles; ++i)
        order[by_home[home(spans[i])]++] = static_cast<std::uint32_t>(i);
    triangles_.resize(triangles);
    parallel_for(triangles, kTrianglesPerTask, threads, [&](std::size_t first, std::size_t last) {
        for (std::size_t p = first; p < last; ++p)
            triangles_[p] = geometry.triangles[order[p]];
    });
    for (std::size_t p = 0; p < triangles; ++p) {
        if (const Span& span = spans[order[p]]; span.c1 < span.c0)
            every_ray_.push_back(static_cast<std::uint32_t>(p));
    }
    for (std::size_t s = 0; s < geometry.spheres.size(); ++s)
        every_ray_.push_back(static_cast<std::uint32_t>(triangles + s));
    // The cells of a triangle's shadow that its projection, grown as the shadow is, may reach: those of the
    // grid's edge (which reach to infinity), and the others unless one of the triangle's edge normals
    // separates the triangle from the cell grown by (grow_u, grow_v) and a bound of the cell's own rounding
    // (the separating axis test, with a margin far above the double rounding of these dot products): the
    // cells' rays then test fewer triangles.
    const double side = cells_per_unit_ > 0.0 ? 1.0 / cells_per_unit_ : 0.0;
    const double reach_u = grow_u + rounding, reach_v = grow_v + rounding;
    const auto each_cell = [&](const Triangle& tri, const Span& span, auto&& body) {
        const Plane corner[3] = {project(tri.v0), project(tri.v1), project(tri.v2)};
        const auto separated = [&](std::size_t r, std::size_t c) {
            if (c == 0 || r == 0 || c + 1 >= columns_ || r + 1 >= rows_) return false;
            const double centre_u = lo_u_ + (static_cast<double>(c) + 0.5) * side;
            const double centre_v = lo_v_ + (static_cast<double>(r) + 0.5) * side;
            const double half_u = 0.5 * side + reach_u, half_v = 0.5 * side + reach_v;
            for (int e = 0; e < 3; ++e) {
                const Plane& a = corner[e];
                const Plane& b = corner[(e + 1) % 3];
                const double normal_u = a.v - b.v, normal_v = b.u - a.u;
                double lo = kInfinity, hi = -kInfinity;
                for (const Plane& p : corner) {
                    const double along = normal_u * p.u + normal_v * p.v;
                    lo = std::min(lo, along), hi = std::max(hi, along);
                }
                const double centre = normal_u * centre_u + normal_v * centre_v;
                const double half = std::fabs(normal_u) * half_u + std::fabs(normal_v) * half_v;
                const double margin = 0x1p-44 * (std::fabs(normal_u) + std::fabs(normal_v)) * reach;
                if (centre - half > hi + margin || centre + half < lo - margin) return true;
            }
            return false;
        };
        for (std::size_t r = span.r0; r <= span.r1; ++r) {
            for (std::size_t c = span.c0; c <= span.c1; ++c) {
                if (!separated(r, c)) body(r * columns_ + c);
            }
        }
    };
    first_.assign(cell_total + 1, 0);
    for (std::size_t p = 0; p < triangles; ++p)
        each_cell(triangles_[p], spans[order[p]], [&](std::size_t cell) { ++first_[cell + 1]; });
    std::inclusive_scan(first_.begin(), first_.end(), first_.begin());
    prims_.resize(first_.back());
    std::vector<std::size_t> next(first_.begin(), first_.end() - 1);
    for (std::size_t p = 0; p < triangles; ++p) {
        each_cell(triangles_[p], spans[order[p]],
                  [&](std::size_t cell) { prims_[next[cell]++] = static_cast<std::uint32_t>(p); });
    }
    // Each cell's triangles by their farthest depth along the direction (ties by index), so that a ray
    // skips the leading ones, which lie wholly behind its origin (far_depth).
    std::vector<double> far(triangles);
    parallel_for(triangles, kTrianglesPerTask, threads, [&](std::size_t first, std::size_t last) {
        for (std::size_t p = first; p < last; ++p)
            far[p] = far_depth(triangles_[p]);
    });
    parallel_for(cell_total, kTrianglesPerTask, threads, [&](std::size_t first, std::size_t last) {
        for (std::size_t cell = first; cell < last; ++cell) {
            std::sort(prims_.begin() + static_cast<std::ptrdiff_t>(first_[cell]),
                      prims_.begin() + static_cast<std::ptrdiff_t>(first_[cell + 1]),
                      [&](std::uint32_t a, std::uint32_t b) {
                          return far[a] < far[b] || (far[a] == far[b] && a < b);
                      });
        }
    });
    listed_.assign((cell_count() + 63) / 64, 0);
    for (std::size_t cell = 0; cell < cell_count(); ++cell) {
        if (first_[cell] != first_[cell + 1]) listed_[cell / 64] |= std::uint64_t{1} << (cell % 64);
    }
}

int CrossingGrid::listed_cells(const Vec3f* origins, const Vec3f& centre, float limit,
                               std::uint32_t* cells) const {
    const bool every = !every_ray_.empty();
    int listed = 0;
#if defined(__AVX2__)
    // The x, y and z of the eight from their 24 floats: each blend gathers one coordinate of every origin,
    // permuted (x0 x3 x6 x1 x4 x7 x2 x5 for x), which one permutation puts in order.
    const float* f = &origins[0].x;
    const __m256 a = _mm256_loadu_ps(f), b = _mm256_loadu_ps(f + 8), c = _mm256_loadu_ps(f + 16);
    // The blend masks are template arguments: VBLENDPS takes its mask as an immediate.
    const auto coordinate = [&]<int kFromA, int kFromB>(__m256i order) {
        return _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(c, a, kFromA), b, kFromB), order);
    };
    const __m256 x = coordinate.operator()<0x49, 0x92>(_mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
    const __m256 y = coordinate.operator()<0x92, 0x24>(_mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6));
    const __m256 z = coordinate.operator()<0x24, 0x49>(_mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
    // Finite and near: |o - centre| <= limit on every axis (a NaN or an infinity fails it). An infinite limit
    // (an empty scene's frame) leaves only the finite check, as is_far and is_finite do.
    const __m256 sign = _mm256_set1_ps(-0.0f);
    const __m256 bound = _mm256_set1_ps(std::min(limit, std::numeric_limits<float>::max()));
    const auto near = [&](__m256 p, float middle) {
        return _mm256_cmp_ps(_mm256_andnot_ps(sign, _mm256_sub_ps(p, _mm256_set1_ps(middle))), bound,
                             _CMP_LE_OQ);
    };
    const __m256 finite = _mm256_and_ps(
        _mm256_cmp_ps(_mm256_andnot_ps(sign, x), _mm256_set1_ps(kInfinity), _CMP_LT_OQ),
        _mm256_and_ps(_mm256_cmp_ps(_mm256_andnot_ps(sign, y), _mm256_set1_ps(kInfinity), _CMP_LT_OQ),
                      _mm256_cmp_ps(_mm256_andnot_ps(sign, z), _mm256_set1_ps(kInfinity), _CMP_LT_OQ)));
    const __m256 ordinary = _mm256_and_ps(
        finite, _mm256_and_ps(near(x, centre.x), _mm256_and_ps(near(y, centre.y), near(z, centre.z))));
    if (_mm256_movemask_ps(ordinary) != 0xff) return -1;
    // cell_of on four origins at a time: dot(Vec3d(p), axis) as ((x a.x + y a.y) + z a.z), and cell_along's
    // floor and clamp (minpd and maxpd return their second operand where one is NaN: NaN to 0, as there).
    const auto four = [&](__m128 px, __m128 py, __m128 pz) {
        const __m256d qx = _mm256_cvtps_pd(px), qy = _mm256_cvtps_pd(py), qz = _mm256_cvtps_pd(pz);
        const auto dot = [&](const Vec3d& axis) {
            return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(qx, _mm256_set1_pd(axis.x)),
                                               _mm256_mul_pd(qy, _mm256_set1_pd(axis.y))),
                                 _mm256_mul_pd(qz, _mm256_set1_pd(axis.z)));
        };
        const auto along = [&](__m256d p, double lo, double last) {
            const __m256d cell = _mm256_floor_pd(
                _mm256_mul_pd(_mm256_sub_pd(p, _mm256_set1_pd(lo)), _mm256_set1_pd(cells_per_unit_)));
            return _mm256_cvttpd_epi32(
                _mm256_max_pd(_mm256_min_pd(_mm256_set1_pd(last), cell), _mm256_setzero_pd()));
        };
        const __m128i column = along(dot(axis_u_), lo_u_, last_column_);
        const __m128i row = along(dot(axis_v_), lo_v_, last_row_);
        return _mm_add_epi32(_mm_mullo_epi32(row, _mm_set1_epi32(static_cast<int>(columns_))), column);
    };
    _mm_storeu_si128(reinterpret_cast<__m128i*>(cells),
                     four(_mm256_castps256_ps128(x), _mm256_castps256_ps128(y), _mm256_castps256_ps128(z)));
    _mm_storeu_si128(
        reinterpret_cast<__m128i*>(cells + 4),
        four(_mm256_extractf128_ps(x, 1), _mm256_extractf128_ps(y, 1), _mm256_extractf128_ps(z, 1)));
#else
    for (int j = 0; j < 8; ++j) {
        const Vec3f& origin = origins[j];
        if (!is_finite(origin) || max_component(abs(origin - centre)) > limit) return -1;
        cells[j] = static_cast<std::uint32_t>(cell_of(origin));
    }
#endif
    for (int j = 0; j < 8; ++j)
        listed |= static_cast<int>(((listed_[cells[j] / 64] >> (cells[j] % 64)) & 1u) | every) << j;
    return listed;
}

std::shared_ptr<const CrossingGrid> CrossingGrids::grid(const Geometry& geometry, const Box3f& bounds,
                                                        const Vec3f& direction, std::size_t cells,
                                                        int threads, std::uint64_t version) {
    {
        const std::lock_guard lock(mutex_);
        if (version != version_) grids_.clear(), version_ = version;
        const auto kept = std::find_if(grids_.begin(), grids_.end(),
                                       [&](const auto& grid) { return grid->direction() == direction; });
        if (kept != grids_.end()) {
            std::rotate(kept, kept + 1, grids_.end());
            return grids_.back();
        }
    }
    auto made = std::make_shared<const CrossingGrid>(geometry, bounds, direction, cells, threads);
    const std::lock_guard lock(mutex_);
    if (version != version_) return made;  // the geometry changed meanwhile: this one is not to keep
    // Another call may have made the same grid meanwhile: one is kept.
    if (std::none_of(grids_.begin(), grids_.end(),
                     [&](const auto& grid) { return grid->direction() == direction; }))
        grids_.push_back(made);
    // The least recently used dropped while the grids kept exceed the budget, the newest kept.
    std::size_t bytes = 0;
    for (const auto& grid : grids_)
        bytes += grid->memory_bytes();
    while (grids_.size() > 1 && bytes > geometry.triangles.size() * sizeof(Triangle)) {
        bytes -= grids_.front()->memory_bytes();
        grids_.erase(grids_.begin());
    }
    return made;
}

}  // namespace lancer
