// The crossing grid's promise to count_crossings: a ray that a triangle test may say hits a triangle starts
// in a cell that lists it. Those hits lie within the geometric tolerance of the triangle, so a point of a
// triangle moved by up to the tolerance on each axis (the corners of that cube the farthest) must lie in a
// cell that lists the triangle, and so must the same point moved back along the direction.
#include "accel/crossing_grid.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <span>
#include <vector>

#include "accel/build_util.hpp"
#include "lancer/generate.hpp"
#include "lancer/ray.hpp"

namespace lancer {
namespace {

bool same_triangle(const Triangle& a, const Triangle& b) {
    return a.v0 == b.v0 && a.v1 == b.v1 && a.v2 == b.v2;
}

bool lists(const CrossingGrid& grid, const Vec3f& origin, const Triangle& tri) {
    const std::span<const std::uint32_t> listed = grid.primitives(grid.cell_of(origin));
    return std::any_of(listed.begin(), listed.end(),
                       [&](std::uint32_t prim) { return same_triangle(grid.triangles()[prim], tri); });
}

// The first coordinate above `from`'s on `axis` (0: x, 1: y; the others fixed) where the cell changes: a
// cell boundary, to a float.
float next_boundary(const CrossingGrid& grid, Vec3f from, int axis) {
    const std::size_t start = grid.cell_of(from);
    const auto at = [&](float coordinate) {
        Vec3f p = from;
        (axis == 0 ? p.x : p.y) = coordinate;
        return grid.cell_of(p);
    };
    const float first = axis == 0 ? from.x : from.y;
    float inside = first, outside = first + 1e-3f;
    while (at(outside) == start)
        outside += outside - first;
    while (std::nextafter(inside, outside) != outside) {
        const float middle = 0.5f * (inside + outside);
        (at(middle) == start ? inside : outside) = middle;
    }
    return outside;
}

// Where a triangle's edge passes a cell's corner from outside the cell closer than the tolerance, the cell
// lists the triangle: the edge test that drops cells a triangle's shadow covers but the triangle does not
// reach grows the cell by the tolerance first. Looking down -z, the grid's cells are squares in x and y; a
// probe triangle inside the sphere's shadow (which leaves the cells as they are) is moved so that its edge
// x + y = c passes half the tolerance below the lower left corner of a cell.
TEST(CrossingGrid, ListsATriangleWhoseEdgePassesACellCornerWithinTheTolerance) {
    std::vector<Triangle> shapes;
    make_icosphere(3, Vec3f(0.0f), 1.0f).append_triangles(shapes);
    shapes.push_back({{0.0f, 0.0f, 2.0f}, {0.1f, 0.0f, 2.0f}, {0.0f, 0.1f, 2.0f}});
    const Box3f bounds = Geometry{shapes, {}}.bounds();
    const float tolerance = geometric_tolerance(bounds);
    const Vec3f down(0.0f, 0.0f, -1.0f);
    const CrossingGrid before(Geometry{shapes, {}}, bounds, down, shapes.size() / 2, 1);
    const Vec3f start(0.05f, 0.05f, 2.0f);
    const float corner_x = next_boundary(before, start, 0), corner_y = next_boundary(before, start, 1);
    const float gap = 0.5f * tolerance, length = 0.02f;
    const float c = corner_x + corner_y - gap;  // the edge's line x + y = c, below the corner
    shapes.back() = {{corner_x - gap - length, corner_y + length, 2.0f},
                     {corner_x + length, corner_y - gap - length, 2.0f},
                     {corner_x - gap - length, corner_y - gap - length, 2.0f}};
    ASSERT_LT(shapes.back().v0.x + shapes.back().v0.y, c + 1e-6f);
    const CrossingGrid grid(Geometry{shapes, {}}, bounds, down, shapes.size() / 2, 1);
    const Vec3f above_corner(corner_x + 0.5f * gap, corner_y + 0.5f * gap, 2.0f);
    ASSERT_EQ(grid.cell_of(above_corner), before.cell_of(above_corner));  // the same cells
    ASSERT_NE(grid.cell_of(above_corner), grid.cell_of({corner_x - 0.5f * gap, corner_y + 0.5f * gap, 2.0f}));
    ASSERT_NE(grid.cell_of(above_corner), grid.cell_of({corner_x + 0.5f * gap, corner_y - 0.5f * gap, 2.0f}));
    // The edge's point nearest the corner, moved towards it by nine tenths of the tolerance on each axis:
    // within the tolerance of the triangle, in the cell beyond the corner.
    const Vec3f near_corner(corner_x - 0.5f * gap + 0.9f * tolerance,
                            corner_y - 0.5f * gap + 0.9f * tolerance, 2.0f);
    ASSERT_EQ(grid.cell_of(near_corner), grid.cell_of(above_corner));
    EXPECT_TRUE(lists(grid, near_corner, shapes.back()));
}

// listed_cells gives eight origins' cells as cell_of does, one by one, and whether each lists anything, or
// -1 when one is not finite or lies beyond the limit: on points uniform around the geometry, points on the
// cells' boundaries (the first float past one and the last before it), points at the limit and past it, and
// NaN and infinite coordinates; on a grid with a triangle listed for every ray, every cell lists.
TEST(CrossingGrid, ListedCellsAreCellOfsEightAtATime) {
    std::vector<Triangle> shapes;
    make_icosphere(3, Vec3f(0.0f), 1.0f).append_triangles(shapes);
    make_torus_knot(24, 6).append_triangles(shapes);
    const Box3f bounds = Geometry{shapes, {}}.bounds();
    const Vec3f centre = bounds.center();
    const float limit = 4.0f * max_component(bounds.extent());
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const Box3f around = bounds.grown(0.2f * length(bounds.extent()));
    std::vector<Triangle> with_apart = shapes;
    with_apart.push_back({{0.0f, 0.0f, kInfinity}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}});
    std::size_t listed_seen = 0, unlisted_seen = 0, refused = 0;
    for (const Vec3f direction : {normalize(Vec3f(0.118f, -0.286f, 0.432f)), Vec3f(0.0f, 0.0f, -1.0f)}) {
        const CrossingGrid grid(Geometry{shapes, {}}, bounds, direction, shapes.size() / 2, 1);
        const CrossingGrid every(Geometry{with_apart, {}}, bounds, direction, with_apart.size() / 2, 1);
        ASSERT_FALSE(every.every_ray().empty());
        std::vector<Vec3f> points;
        for (int n = 0; n < 4000; ++n) {
            const Vec3f p = around.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * around.extent();
            points.push_back(p);
            // The two floats either side of a boundary, where one lies ahead along x (beyond the last
            // cell, none does).
            if (n % 8 == 0 && grid.cell_of({p.x + around.extent().x, p.y, p.z}) != grid.cell_of(p)) {
                const float x = next_boundary(grid, p, 0);
                points.push_back({x, p.y, p.z});
                points.push_back({std::nextafter(x, -kInfinity), p.y, p.z});
            }
        }
        const std::size_t ordinary = points.size() / 8 * 8;
        points.resize(ordinary);
        for (const Vec3f& odd :
             {Vec3f(centre.x + limit, centre.y, centre.z), Vec3f(centre.x, centre.y - limit, centre.z),
              Vec3f(centre.x, centre.y, std::nextafter(centre.z + limit, kInfinity)),
              Vec3f(std::nanf(""), 0.0f, 0.0f), Vec3f(0.0f, -kInfinity, 0.0f), Vec3f(0.0f, 0.0f, kInfinity),
              Vec3f(3e38f, 0.0f, 0.0f)}) {
            for (int slot = 0; slot < 8; ++slot) {  // in every lane, among ordinary points
                for (int j = 0; j < 8; ++j)
                    points.push_back(j == slot ? odd : points[static_cast<std::size_t>(j)]);
            }
        }
        for (const CrossingGrid* g : {&grid, &every}) {
            for (std::size_t first = 0; first < points.size(); first += 8) {
                std::uint32_t cells[8];
                const int listed = g->listed_cells(&points[first], centre, limit, cells);
                bool expected_refused = false;
                for (std::size_t j = first; j < first + 8; ++j) {
                    const Vec3f& p = points[j];
                    expected_refused |= !is_finite(p) || max_component(abs(p - centre)) > limit;
                }
                ASSERT_EQ(listed < 0, expected_refused) << "origins from " << first;
                if (listed < 0) {
                    ++refused;
                    continue;
                }
                for (std::size_t j = 0; j < 8; ++j) {
                    const std::size_t cell = g->cell_of(points[first + j]);
                    ASSERT_EQ(cells[j], cell) << "origin " << first + j;
                    const bool lists = ((listed >> j) & 1) != 0;
                    ASSERT_EQ(lists, g->lists_any(cell)) << "origin " << first + j;
                    (lists ? listed_seen : unlisted_seen) += g == &grid ? 1 : 0;
                    ASSERT_TRUE(lists || g != &every);
                }
            }
        }
    }
    EXPECT_GT(listed_seen, 1000u);
    EXPECT_GT(unlisted_seen, 1000u);
    // The non-finite points and the far ones (those at the limit's float may fall either side of it).
    EXPECT_GE(refused, 2u * 2u * 4u * 8u);
    EXPECT_LE(refused, 2u * 2u * 7u * 8u);
}

}  // namespace
}  // namespace lancer
