#include "scene/polygon.hpp"

#include <cstddef>
#include <utility>

namespace lancer {

namespace {

// Projected coordinates in double: ear tests compare signs of small cross products.
struct Point2 {
    double x = 0.0, y = 0.0;
    bool operator==(const Point2&) const = default;
};

// Twice the signed area of (a, b, c): positive when the three turn counter-clockwise.
double orientation(Point2 a, Point2 b, Point2 c) {
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

bool inside_or_on(Point2 p, Point2 a, Point2 b, Point2 c) {
    return orientation(a, b, p) >= 0.0 && orientation(b, c, p) >= 0.0 && orientation(c, a, p) >= 0.0;
}

// Newell's method: the area vector of the whole outline, pointing to the side it runs counter-clockwise
// around. It stays right when some corners are flat or nearly so. The sum does not depend on the origin;
// taking the first vertex as origin keeps far-off polygons from cancelling away their digits.
Vec3f newell_normal(std::span<const Vec3f> polygon) {
    Vec3f normal;
    const Vec3f origin = polygon[0];
    for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
        const Vec3f a = polygon[j] - origin, b = polygon[i] - origin;
        normal += Vec3f{(a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y)};
    }
    return normal;
}

// The outline dropped onto the two axes other than the dominant one of its normal, in the order that keeps
// it counter-clockwise. Newell's normal rather than the first corner's picks the plane: a nearly flat first
// corner can point anywhere, and for a valid NFF polygon the two agree.
std::vector<Point2> project(std::span<const Vec3f> polygon) {
    const Vec3f normal = newell_normal(polygon);
    const int axis = max_axis(abs(normal));
    int u = (axis + 1) % 3, v = (axis + 2) % 3;
    if (normal[axis] < 0.0f) std::swap(u, v);
    std::vector<Point2> points;
    points.reserve(polygon.size());
    for (const Vec3f& p : polygon)
        points.push_back({p[u], p[v]});
    return points;
}

bool is_convex(const std::vector<Point2>& points) {
    const std::size_t n = points.size();
    for (std::size_t i = 0; i < n; ++i) {
        if (orientation(points[(i + n - 1) % n], points[i], points[(i + 1) % n]) < 0.0) return false;
    }
    return true;
}

// Ear clipping on a doubly linked ring (Meisters' two-ears theorem: a simple polygon always has an ear).
// An ear is a strictly convex corner whose triangle holds no other remaining vertex. A vertex that
// coincides with an end of the ear's diagonal does not block it (an outline that touches itself there); one
// that coincides with the ear's tip does, since the diagonal would then cut the outline off at that point.
void clip_ears(const std::vector<Point2>& points, std::vector<std::uint32_t>& triangles) {
    const auto n = static_cast<std::uint32_t>(points.size());
    std::vector<std::uint32_t> prev(n), next(n);
    for (std::uint32_t i = 0; i < n; ++i)
        prev[i] = (i + n - 1) % n, next[i] = (i + 1) % n;

    const auto turn = [&](std::uint32_t corner) {
        return orientation(points[prev[corner]], points[corner], points[next[corner]]);
    };
    const auto is_ear = [&](std::uint32_t corner) {
        const std::uint32_t a = prev[corner], c = next[corner];
        const Point2 pa = points[a], pb = points[corner], pc = points[c];
        if (orientation(pa, pb, pc) <= 0.0) return false;
        for (std::uint32_t other = next[c]; other != a; other = next[other]) {
            const Point2 p = points[other];
            if (p == pa || p == pc) continue;
            if (inside_or_on(p, pa, pb, pc)) return false;
        }
        return true;
    };
    // When a whole lap finds no ear, the outline left is not simple (it overlaps itself, or has collapsed
    // to zero area). Clipping a flat corner costs no area; failing that, the most convex corner goes, so
    // that the loop ends with n - 2 triangles whatever the input.
    const auto fallback = [&](std::uint32_t start) {
        std::uint32_t best = start, corner = start;
        do {
            if (turn(corner) == 0.0) return corner;
            if (turn(corner) > turn(best)) best = corner;
            corner = next[corner];
        } while (corner != start);
        return best;
    };
    const auto clip = [&](std::uint32_t corner) {
        triangles.insert(triangles.end(), {prev[corner], corner, next[corner]});
        next[prev[corner]] = next[corner];
        prev[next[corner]] = prev[corner];
        return next[corner];
    };

    std::uint32_t corner = 0;
    std::uint32_t left = n;
    std::uint32_t tried = 0;  // corners tried since the last clip
    while (left > 3) {
        if (is_ear(corner)) {
            corner = clip(corner), --left, tried = 0;
        } else if (++tried == left) {
            corner = clip(fallback(corner)), --left, tried = 0;
        } else {
            corner = next[corner];
        }
    }
    clip(corner);
}

}  // namespace

Vec3f polygon_normal(std::span<const Vec3f> polygon) {
    if (polygon.size() < 3) return {};
    const Vec3f corner = cross(polygon[1] - polygon[0], polygon[2] - polygon[1]);
    return corner != Vec3f{} ? corner : newell_normal(polygon);
}

bool triangulate_polygon(std::span<const Vec3f> polygon, std::vector<std::uint32_t>& triangles) {
    const auto n = static_cast<std::uint32_t>(polygon.size());
    if (n < 3) return true;
    const std::vector<Point2> points = project(polygon);
    if (n > 3 && !is_convex(points)) {
        if (n > kMaxEarClippedVertices) return false;
        clip_ears(points, triangles);
        return true;
    }
    for (std::uint32_t k = 1; k + 1 < n; ++k)
        triangles.insert(triangles.end(), {0u, k, k + 1});
    return true;
}

}  // namespace lancer
