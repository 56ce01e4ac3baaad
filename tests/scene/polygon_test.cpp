// triangulate_polygon: fans for convex outlines, ear clipping for concave ones, in any plane and
// orientation; the triangles cover the polygon exactly once and keep its winding.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "scene/polygon.hpp"

namespace lancer {
namespace {

// A gear outline like the SPD's: `teeth` teeth, each a notch cut into a disc, counter-clockwise in the
// xy plane. Concave at every notch.
std::vector<Vec3f> gear(int teeth, float outer, float inner) {
    std::vector<Vec3f> outline;
    for (int tooth = 0; tooth < teeth; ++tooth) {
        const float step = 2.0f * std::numbers::pi_v<float> / static_cast<float>(teeth);
        const float start = step * static_cast<float>(tooth);
        for (const auto& [fraction, radius] :
             {std::pair{0.0f, outer}, {0.25f, outer}, {0.3f, inner}, {0.7f, inner}, {0.75f, outer}}) {
            const float angle = start + fraction * step;
            outline.push_back({radius * std::cos(angle), radius * std::sin(angle), 0.0f});
        }
    }
    return outline;
}

// Twice the polygon's area from the shoelace formula in xy.
double shoelace(const std::vector<Vec3f>& outline) {
    double twice = 0.0;
    for (std::size_t i = 0, j = outline.size() - 1; i < outline.size(); j = i++) {
        twice += static_cast<double>(outline[j].x) * outline[i].y -
                 static_cast<double>(outline[i].x) * outline[j].y;
    }
    return twice;
}

// Moves a polygon of the xy plane onto another plane by a rotation: (x, y, z) -> x a + y b + z (a x b).
std::vector<Vec3f> rotate(const std::vector<Vec3f>& outline, Vec3f a, Vec3f b) {
    const Vec3f c = cross(a, b);
    std::vector<Vec3f> moved;
    for (const Vec3f& p : outline)
        moved.push_back(p.x * a + p.y * b + p.z * c);
    return moved;
}

struct Check {
    double area = 0.0;
    bool winding_kept = true;
};

// Sums the triangle areas and checks that every triangle faces the same side as `front`.
Check check_triangles(const std::vector<Vec3f>& outline, const std::vector<std::uint32_t>& triangles,
                      Vec3f front) {
    Check check;
    for (std::size_t i = 0; i < triangles.size(); i += 3) {
        const Vec3f a = outline[triangles[i]], b = outline[triangles[i + 1]], c = outline[triangles[i + 2]];
        const Vec3f normal = cross(b - a, c - a);
        check.area += length(normal) / 2.0;
        if (dot(normal, front) < 0.0f) check.winding_kept = false;
    }
    return check;
}

TEST(TriangulatePolygon, ConvexPolygonIsTheFanFromTheFirstVertex) {
    const std::vector<Vec3f> pentagon = {{0, 0, 0}, {2, 0, 0}, {3, 1, 0}, {1, 2, 0}, {-1, 1, 0}};
    std::vector<std::uint32_t> triangles;
    ASSERT_TRUE(triangulate_polygon(pentagon, triangles));
    EXPECT_EQ(triangles, (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3, 0, 3, 4}));
}

TEST(TriangulatePolygon, AppendsAfterWhatIsThere) {
    const std::vector<Vec3f> triangle = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    std::vector<std::uint32_t> triangles = {7, 7, 7};
    ASSERT_TRUE(triangulate_polygon(triangle, triangles));
    EXPECT_EQ(triangles, (std::vector<std::uint32_t>{7, 7, 7, 0, 1, 2}));
}

TEST(TriangulatePolygon, ConcaveLIsEarClippedWithoutSpillingOutside) {
    // Fanning from vertex 0 would cover the notch: triangle (0, 3, 4) lies partly outside the L.
    const std::vector<Vec3f> l_shape = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0}};
    std::vector<std::uint32_t> triangles;
    ASSERT_TRUE(triangulate_polygon(l_shape, triangles));
    ASSERT_EQ(triangles.size(), 3u * 4u);
    const Check check = check_triangles(l_shape, triangles, {0, 0, 1});
    EXPECT_NEAR(check.area, 3.0, 1e-9);
    EXPECT_TRUE(check.winding_kept);
}

TEST(TriangulatePolygon, GearKeepsAreaAndWindingInEveryPlaneAndOrientation) {
    const std::vector<Vec3f> flat = gear(29, 1.0f, 0.8f);  // 145 vertices, like the SPD gear faces
    const double expected_area = shoelace(flat) / 2.0;
    const Vec3f x{1, 0, 0}, y{0, 1, 0}, z{0, 0, 1};
    const Vec3f tilted_a = normalize(Vec3f(1, 1, 0)), tilted_b = normalize(Vec3f(-1, 1, 1));
    const Vec3f tilted_b_orthogonal = normalize(tilted_b - dot(tilted_b, tilted_a) * tilted_a);
    // (a, b) frames: the polygon's front ends up along a x b; the swapped frames make it clockwise as seen
    // from the positive side of its dominant axis.
    const std::vector<std::pair<Vec3f, Vec3f>> frames = {{x, y},
                                                         {y, x},
                                                         {y, z},
                                                         {z, y},
                                                         {z, x},
                                                         {x, z},
                                                         {tilted_a, tilted_b_orthogonal},
                                                         {tilted_b_orthogonal, tilted_a}};
    for (const auto& [a, b] : frames) {
        const std::vector<Vec3f> outline = rotate(flat, a, b);
        std::vector<std::uint32_t> triangles;
        ASSERT_TRUE(triangulate_polygon(outline, triangles));
        ASSERT_EQ(triangles.size(), 3 * (outline.size() - 2));
        const Check check = check_triangles(outline, triangles, cross(a, b));
        EXPECT_NEAR(check.area, expected_area, 1e-4 * expected_area);
        EXPECT_TRUE(check.winding_kept);
    }
}

TEST(TriangulatePolygon, FarFromTheOriginKeepsAreaAndWinding) {
    const std::vector<Vec3f> flat = gear(29, 1.0f, 0.8f);
    const Vec3f a = normalize(Vec3f(1, 1, 0)), b = normalize(Vec3f(-1, 1, 1));
    const Vec3f b_orthogonal = normalize(b - dot(b, a) * a);
    std::vector<Vec3f> outline = rotate(flat, a, b_orthogonal);
    for (Vec3f& p : outline)
        p += Vec3f(1000.0f, -2000.0f, 500.0f);
    std::vector<std::uint32_t> triangles;
    ASSERT_TRUE(triangulate_polygon(outline, triangles));
    ASSERT_EQ(triangles.size(), 3 * (outline.size() - 2));
    const Check check = check_triangles(outline, triangles, cross(a, b_orthogonal));
    const double expected_area = shoelace(flat) / 2.0;
    EXPECT_NEAR(check.area, expected_area, 1e-2 * expected_area);
    EXPECT_TRUE(check.winding_kept);
}

TEST(TriangulatePolygon, UsesEveryVertexAndOnlyValidIndices) {
    const std::vector<Vec3f> outline = gear(8, 2.0f, 1.0f);
    std::vector<std::uint32_t> triangles;
    ASSERT_TRUE(triangulate_polygon(outline, triangles));
    std::vector<bool> used(outline.size(), false);
    for (const std::uint32_t index : triangles) {
        ASSERT_LT(index, outline.size());
        used[index] = true;
    }
    for (std::size_t i = 0; i < used.size(); ++i)
        EXPECT_TRUE(used[i]) << i;
}

TEST(TriangulatePolygon, DegenerateOutlinesStillEndWithNMinusTwoTriangles) {
    // All on a line, and a bow tie (self-intersecting): no valid triangulation, but no hang either.
    const std::vector<Vec3f> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}};
    const std::vector<Vec3f> bow_tie = {{0, 0, 0}, {2, 2, 0}, {2, 0, 0}, {0, 2, 0}, {-1, 1, 0}};
    for (const auto& outline : {line, bow_tie}) {
        std::vector<std::uint32_t> triangles;
        ASSERT_TRUE(triangulate_polygon(outline, triangles));
        EXPECT_EQ(triangles.size(), 3 * (outline.size() - 2));
        for (const std::uint32_t index : triangles)
            EXPECT_LT(index, outline.size());
    }
}

TEST(TriangulatePolygon, ARepeatedVertexDoesNotBlockEars) {
    // Two unit squares touching at (1, 1), one outline that passes that point twice.
    const std::vector<Vec3f> outline = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {2, 1, 0},
                                        {2, 2, 0}, {1, 2, 0}, {1, 1, 0}, {0, 1, 0}};
    std::vector<std::uint32_t> triangles;
    ASSERT_TRUE(triangulate_polygon(outline, triangles));
    ASSERT_EQ(triangles.size(), 3u * 6u);
    const Check check = check_triangles(outline, triangles, {0, 0, 1});
    EXPECT_NEAR(check.area, 2.0, 1e-9);
    EXPECT_TRUE(check.winding_kept);
}

// The outline of the square [0, side]^2 through every integer point of its edges: exactly convex in float
// (its flat corners turn by exactly 0), 4 * side vertices.
std::vector<Vec3f> square_of_integer_points(int side) {
    std::vector<Vec3f> outline;
    for (int i = 0; i < side; ++i)
        outline.push_back({static_cast<float>(i), 0.0f, 0.0f});
    for (int i = 0; i < side; ++i)
        outline.push_back({static_cast<float>(side), static_cast<float>(i), 0.0f});
    for (int i = side; i > 0; --i)
        outline.push_back({static_cast<float>(i), static_cast<float>(side), 0.0f});
    for (int i = side; i > 0; --i)
        outline.push_back({0.0f, static_cast<float>(i), 0.0f});
    return outline;
}

TEST(TriangulatePolygon, AHundredThousandVertexConvexPolygonIsAFan) {
    const std::vector<Vec3f> outline = square_of_integer_points(25'000);
    ASSERT_EQ(outline.size(), 100'000u);
    std::vector<std::uint32_t> triangles;
    ASSERT_TRUE(triangulate_polygon(outline, triangles));
    ASSERT_EQ(triangles.size(), 3 * (outline.size() - 2));
    for (std::size_t i = 0; i < triangles.size(); i += 3) {
        const std::uint32_t k = static_cast<std::uint32_t>(i / 3) + 1;
        ASSERT_EQ(triangles[i], 0u);
        ASSERT_EQ(triangles[i + 1], k);
        ASSERT_EQ(triangles[i + 2], k + 1);
    }
    const Check check = check_triangles(outline, triangles, {0, 0, 1});
    EXPECT_NEAR(check.area, 25'000.0 * 25'000.0, 1e-6 * 25'000.0 * 25'000.0);
}

TEST(TriangulatePolygon, AConcavePolygonPastTheEarClippingBoundIsRefused) {
    // A gear is concave at every notch: 5 vertices per tooth.
    const std::vector<Vec3f> at_bound = gear(static_cast<int>(kMaxEarClippedVertices / 5), 2.0f, 1.5f);
    std::vector<std::uint32_t> triangles;
    ASSERT_TRUE(triangulate_polygon(at_bound, triangles));
    EXPECT_EQ(triangles.size(), 3 * (at_bound.size() - 2));
    EXPECT_NEAR(check_triangles(at_bound, triangles, {0, 0, 1}).area, shoelace(at_bound) / 2.0,
                1e-3 * shoelace(at_bound));

    const std::vector<Vec3f> past_bound = gear(20'000, 2.0f, 1.5f);
    triangles.clear();
    EXPECT_FALSE(triangulate_polygon(past_bound, triangles));
    EXPECT_TRUE(triangles.empty());
}

TEST(PolygonNormal, FollowsTheFirstCornerAndFallsBackToNewell) {
    const std::vector<Vec3f> square = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    EXPECT_EQ(polygon_normal(square), Vec3f(0, 0, 1));
    // First three vertices on a line: Newell's normal of the whole outline, twice its area.
    const std::vector<Vec3f> flat_start = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}};
    EXPECT_EQ(polygon_normal(flat_start), Vec3f(0, 0, 8));
    const std::vector<Vec3f> clockwise = {{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
    EXPECT_EQ(polygon_normal(clockwise), Vec3f(0, 0, -1));
}

}  // namespace
}  // namespace lancer
