// The lookup tables of Portalez & Duguet (2016), section 4.2 (conventions.hpp) against slab computations: the
// exit face (equations 6-8) must be an axis of smallest slab exit, the sub-face (equations 9-10) the quadrant
// of the face that holds the ray's crossing point, on exhaustive integer samples (every octant, every order
// of the three exits with ties and infinite exits, crossings on the median lines, zero and negative-zero
// components) and on random rays in floating point. Also: the seed's own tables (7)-(9) are ours after a
// renumbering of faces and vertices, which fixes the conventions of its missing Figure 4.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "accel/plucker/conventions.hpp"
#include "accel/plucker/walk.hpp"

namespace lancer::plucker {
namespace {

// An exit face is right when its slab exit is the smallest (ties: any of the tied axes).
bool is_first_exit(const std::array<double, 3>& t, int face) {
    const double smallest = std::min({t[0], t[1], t[2]});
    return t[static_cast<std::size_t>(face_axis(face))] == smallest;
}

// The octant a WalkRay gives a ray whose origin is `origin` in the unit root cube.
WalkRay walk_ray(const Vec3f& origin, const Vec3f& direction) {
    return WalkRay({origin, direction, 0.0f, kInfinity}, OctreeCube{Vec3f(-100.0f), 200.0f}, kTables);
}

TEST(PluckerTables, AreTheSeedsTablesRenumbered) {
    // Portalez & Duguet (2016), equations (7)-(9). Its faces 0..5 are our -y, -x, +y, +x, -z, +z; its row r
    // of (8) is our octant 7 - r (its vertex bits are set for the lower coordinate); its 7 is "cannot
    // happen".
    constexpr int kSeedFace[6] = {2, 0, 3, 1, 4, 5};
    constexpr int kSeedExit[8][8] = {{7, 2, 5, 2, 3, 3, 5, 7}, {5, 7, 1, 1, 5, 2, 7, 2},
                                     {3, 3, 7, 5, 0, 7, 0, 5}, {0, 5, 0, 7, 7, 5, 1, 1},
                                     {2, 4, 2, 7, 7, 4, 3, 3}, {1, 1, 7, 4, 2, 7, 2, 4},
                                     {4, 7, 3, 3, 4, 0, 7, 0}, {7, 0, 4, 0, 1, 1, 4, 7}};
    constexpr int kSeedNeighbour[6][8] = {{1, 3, 1, 3, 0, 2, 0, 2}, {2, 2, 0, 0, 3, 3, 1, 1},
                                          {2, 0, 2, 0, 3, 1, 3, 1}, {1, 1, 3, 3, 0, 0, 2, 2},
                                          {2, 0, 3, 1, 2, 0, 3, 1}, {1, 3, 0, 2, 1, 3, 0, 2}};
    for (int row = 0; row < 8; ++row) {
        const auto octant = static_cast<std::size_t>(7 - row);
        for (std::size_t pattern = 0; pattern < 8; ++pattern) {
            const int seed = kSeedExit[row][pattern];
            if (seed == 7) {
                EXPECT_FALSE(kExitTables.derived[octant][pattern]) << "row " << row << " pattern " << pattern;
            } else {
                EXPECT_TRUE(kExitTables.derived[octant][pattern]);
                EXPECT_EQ(kExitFace[octant][pattern], kSeedFace[seed])
                    << "row " << row << " pattern " << pattern;
            }
        }
    }
    for (int face = 0; face < 6; ++face) {
        for (std::size_t pattern = 0; pattern < 8; ++pattern) {
            EXPECT_EQ(kNeighbourQuadrant[static_cast<std::size_t>(kSeedFace[face])][pattern],
                      kSeedNeighbour[face][pattern])
                << "seed face " << face << " pattern " << pattern;
        }
    }
}

// Every octant, every weak order of the three slab exits (13 of them, ties included) and exits at +inf
// (zero components, of either sign), with several speeds per axis: all products are small integers, so the
// signs are exact and the table alone is tested.
TEST(PluckerTables, ExitFaceIsAFirstSlabExitForEveryOrderTieAndZeroComponent) {
    constexpr float kCell = 8.0f;
    constexpr double kNever = std::numeric_limits<double>::infinity();
    const std::array<float, 3> speeds = {1.0f, 0.5f, 2.0f};
    int checked = 0;
    for (int octant = 0; octant < 8; ++octant) {
        // rank 0: the axis does not move (zero component); ranks 1..3 are exit times, repeated for ties.
        for (int ranks = 0; ranks < 64; ++ranks) {
            const std::array<int, 3> rank = {ranks & 3, (ranks >> 2) & 3, (ranks >> 4) & 3};
            if (rank[0] == 0 && rank[1] == 0 && rank[2] == 0) continue;  // a zero direction is invalid
            for (int speed = 0; speed < 27; ++speed) {
                for (int negative_zero = 0; negative_zero < 2; ++negative_zero) {
                    Vec3f origin, direction, vertex;
                    std::array<double, 3> t{};
                    for (int axis = 0; axis < 3; ++axis) {
                        const bool up = (octant >> axis) & 1;
                        vertex[axis] = up ? kCell : 0.0f;
                        const float s = speeds[static_cast<std::size_t>(speed /
                                                                        (axis == 0   ? 1
                                                                         : axis == 1 ? 3
                                                                                     : 9) %
                                                                        3)];
                        if (rank[static_cast<std::size_t>(axis)] == 0) {
                            // Not moving: the origin strictly inside the slab (the walk's invariant), on the
                            // side that gives the wanted octant (WalkRay's rule for zero components).
                            direction[axis] = negative_zero ? -0.0f : 0.0f;
                            origin[axis] = up ? -1.0f : 1.0f;
                            t[static_cast<std::size_t>(axis)] = kNever;
                            vertex[axis] = up ? 3.0f : -3.0f;
                            continue;
                        }
                        direction[axis] = up ? s : -s;
                        origin[axis] =
                            vertex[axis] -
                            static_cast<float>(rank[static_cast<std::size_t>(axis)]) * direction[axis];
                        t[static_cast<std::size_t>(axis)] = rank[static_cast<std::size_t>(axis)];
                    }
                    const WalkRay ray = walk_ray(origin, direction);
                    ASSERT_EQ(ray.octant, octant);
                    const int face = exit_face(ray, vertex - origin);
                    ASSERT_TRUE(is_first_exit(t, face)) << "octant " << octant << " ranks " << rank[0]
                                                        << rank[1] << rank[2] << " face " << face;
                    ASSERT_EQ(face_side(face), (octant >> face_axis(face)) & 1);
                    ++checked;
                }
            }
        }
    }
    EXPECT_GT(checked, 20000);
}

// Random cells and rays in floating point against slab exits computed in double. Rounding may pick a face
// whose exit is within rounding of the first one: accepted within a relative 1e-5 of the distance.
// Random cells and rays: the exit face is a first slab exit, or within rounding of one. `denormal`: a third
// of the components are denormal (below 2^-126 of the others), and the origin lies on such an axis's exit
// plane half the time, where the exact product d x w on the other axes is d_denormal w alone (fuzz finding
// 24: in float it underflowed to 0, and the walk left a cell by a face 0.05 units beyond the first exit).
void expect_exit_faces_match_slabs(bool denormal) {
    std::mt19937 rng(42);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    int exact = 0, within_rounding = 0;
    constexpr int kRays = 200000;
    for (int i = 0; i < kRays; ++i) {
        const float size = std::ldexp(1.0f, static_cast<int>(unit(rng) * 8.0f));
        const Vec3f lo = Vec3f(unit(rng), unit(rng), unit(rng)) * 100.0f;
        Vec3f direction(unit(rng), unit(rng), unit(rng));
        for (int axis = 0; axis < 3; ++axis) {
            if (rng() % 5 == 0) direction[axis] = rng() % 2 ? 0.0f : -0.0f;
            if (denormal && rng() % 3 == 0)
                direction[axis] = std::ldexp(unit(rng), -126 - static_cast<int>(rng() % 24));
        }
        if (direction == Vec3f(0.0f)) direction.z = 1.0f;
        // An origin inside the cell, or outside but behind it.
        Vec3f origin = lo + Vec3f(size) * Vec3f((unit(rng) + 1.0f) / 2.0f, (unit(rng) + 1.0f) / 2.0f,
                                                (unit(rng) + 1.0f) / 2.0f);
        if (rng() % 2) origin = origin - direction * (size * 3.0f * (unit(rng) + 1.0f));
        for (int axis = 0; axis < 3; ++axis) {
            const float d = direction[axis];
            if (denormal && d != 0.0f && std::fabs(d) < std::numeric_limits<float>::min() && rng() % 2)
                origin[axis] = d > 0.0f ? lo[axis] + size : lo[axis];
        }
        const WalkRay ray = walk_ray(origin, direction);
        Vec3f vertex;
        std::array<double, 3> t{};
        bool inside_zero_slabs = true;
        for (int axis = 0; axis < 3; ++axis) {
            const bool up = ray.up(axis) == 1u;
            vertex[axis] = up ? lo[axis] + size : lo[axis];
            if (direction[axis] == 0.0f) {
                t[static_cast<std::size_t>(axis)] = std::numeric_limits<double>::infinity();
                inside_zero_slabs &= up ? origin[axis] < vertex[axis] : origin[axis] > vertex[axis];
            } else {
                t[static_cast<std::size_t>(axis)] =
                    (static_cast<double>(vertex[axis]) - origin[axis]) / static_cast<double>(direction[axis]);
            }
        }
        if (!inside_zero_slabs) continue;  // the walk never visits such a cell
        const int face = exit_face(ray, vertex - origin);
        const double smallest = std::min({t[0], t[1], t[2]});
        const double chosen = t[static_cast<std::size_t>(face_axis(face))];
        if (chosen == smallest) {
            ++exact;
        } else {
            ASSERT_LE(chosen - smallest, 1e-5 * (std::fabs(smallest) + size / length(direction)))
                << "ray " << i << " face " << face;
            ++within_rounding;
        }
    }
    EXPECT_GT(exact, kRays / 2);
    EXPECT_LT(within_rounding, kRays / 1000);
}

TEST(PluckerTables, ExitFaceMatchesSlabsOnRandomRays) {
    expect_exit_faces_match_slabs(false);
}

TEST(PluckerTables, ExitFaceMatchesSlabsWithDenormalComponents) {
    expect_exit_faces_match_slabs(true);
}

// The quadrant of a face that holds a crossing point at in-face coordinates (a, b) with the face's centre
// at (mid_a, mid_b): a point on a median goes to the octant's side.
std::uint32_t slab_quadrant(const WalkRay& ray, int face, double a, double b, double mid_a, double mid_b) {
    const int u = lower_in_face_axis(face_axis(face)), v = upper_in_face_axis(face_axis(face));
    const auto upper = [&](int axis, double x, double mid) {
        return x > mid || (x == mid && ray.up(axis) == 1u);
    };
    return (upper(u, a, mid_a) ? 1u : 0u) | (upper(v, b, mid_b) ? 2u : 0u);
}

// Exhaustive on integer samples: every face, crossings at every point of a 9 x 9 lattice of the face (the
// medians and the edges included), every in-face direction (positive, negative, +0, -0).
TEST(PluckerTables, SubFaceIsTheQuadrantOfTheCrossingPointIncludingMedians) {
    constexpr float kCell = 8.0f;
    const std::array<float, 4> in_face_speeds = {1.0f, -1.0f, 0.0f, -0.0f};
    int checked = 0;
    for (int face = 0; face < 6; ++face) {
        const int normal = face_axis(face), side = face_side(face);
        const int u = lower_in_face_axis(normal), v = upper_in_face_axis(normal);
        for (int a = 0; a <= 8; ++a) {
            for (int b = 0; b <= 8; ++b) {
                for (const float du : in_face_speeds) {
                    for (const float dv : in_face_speeds) {
                        Vec3f crossing, direction, centre;
                        crossing[normal] = side ? kCell : 0.0f;
                        crossing[u] = static_cast<float>(a);
                        crossing[v] = static_cast<float>(b);
                        direction[normal] = side ? 2.0f : -2.0f;
                        direction[u] = du;
                        direction[v] = dv;
                        const Vec3f origin = crossing - direction;  // crosses at t = 1
                        centre[normal] = crossing[normal];
                        centre[u] = centre[v] = kCell / 2.0f;
                        // Root centre far away on the low side: zero in-face components count as moving up
                        // unless their coordinate is above the root's centre, as WalkRay decides.
                        const WalkRay ray = walk_ray(origin, direction);
                        const std::uint32_t expected =
                            slab_quadrant(ray, face, crossing[u], crossing[v], kCell / 2.0, kCell / 2.0);
                        ASSERT_EQ(sub_face(ray, kTables, face, centre - origin), expected)
                            << "face " << face << " crossing (" << a << ", " << b << ") d (" << du << ", "
                            << dv << ")";
                        ++checked;
                    }
                }
            }
        }
    }
    EXPECT_EQ(checked, 6 * 81 * 16);
}

TEST(PluckerTables, SubFaceMatchesTheCrossingPointOnRandomRays) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    int off_by_rounding = 0;
    constexpr int kRays = 200000;
    for (int i = 0; i < kRays; ++i) {
        const int face = static_cast<int>(rng() % 6);
        const int normal = face_axis(face), side = face_side(face);
        const int u = lower_in_face_axis(normal), v = upper_in_face_axis(normal);
        const float size = std::ldexp(1.0f, static_cast<int>(unit(rng) * 8.0f));
        const Vec3f lo = Vec3f(unit(rng), unit(rng), unit(rng)) * 100.0f;
        Vec3f direction(unit(rng), unit(rng), unit(rng));
        direction[normal] = (side ? 1.0f : -1.0f) * (0.05f + std::fabs(direction[normal]));
        if (rng() % 4 == 0) direction[u] = 0.0f;
        Vec3f origin = lo + Vec3f(size) * Vec3f((unit(rng) + 1.0f) / 2.0f, (unit(rng) + 1.0f) / 2.0f,
                                                (unit(rng) + 1.0f) / 2.0f);
        const WalkRay ray = walk_ray(origin, direction);
        Vec3f centre = lo + Vec3f(size / 2.0f);
        centre[normal] = side ? lo[normal] + size : lo[normal];
        const double t = (static_cast<double>(centre[normal]) - origin[normal]) / direction[normal];
        const double a = origin[u] + t * direction[u], b = origin[v] + t * direction[v];
        const std::uint32_t expected = slab_quadrant(ray, face, a, b, centre[u], centre[v]);
        const std::uint32_t q = sub_face(ray, kTables, face, centre - origin);
        if (q != expected) {
            // Only a crossing within rounding of a median may go to the other side.
            const double margin = 1e-5 * (size + length(centre - origin));
            const bool near_median = std::fabs(a - centre[u]) < margin || std::fabs(b - centre[v]) < margin;
            ASSERT_TRUE(near_median) << "ray " << i;
            ++off_by_rounding;
        }
    }
    EXPECT_LT(off_by_rounding, kRays / 1000);
}

}  // namespace
}  // namespace lancer::plucker
