#include "lancer/queries.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "accel/bvh/bvh.hpp"
#include "accel/primitive_intersect.hpp"

namespace lancer {

struct GeometryQueries::Impl {
    Geometry geometry;
    TriangleTest test = TriangleTest::MollerTrumbore;
    BvhAccel bvh;
};

GeometryQueries::GeometryQueries(const Geometry& geometry, TriangleTest test)
    : impl_(std::make_unique<Impl>()) {
    impl_->geometry = geometry;
    impl_->test = test;
    impl_->bvh.build(geometry, build_options(test));
}

GeometryQueries::~GeometryQueries() = default;

void GeometryQueries::all_hits(const Ray& ray, std::vector<Hit>& hits) const {
    const std::vector<BvhNode>& nodes = impl_->bvh.nodes();
    const std::vector<std::uint32_t>& prim_indices = impl_->bvh.prim_indices();
    if (!is_valid(ray) || nodes.empty()) return;
    const std::size_t first = hits.size();
    dispatch_policies(impl_->test, false, [&]<class TriangleTestT, bool>() {
        const PreparedRay<TriangleTestT> prepared(ray);
        const SlabRay slab(ray);
        // Every node whose box the ray crosses within [tnear, tfar], in any order: both children of a node
        // may wait, so the stack holds at most one node per level and the root.
        std::array<std::uint32_t, BvhAccel::kMaxDepth + 2> stack;
        std::size_t size = 0;
        float t_entry, t_exit;
        if (intersect_box(slab, nodes[0].bounds(), ray.tnear, ray.tfar, t_entry, t_exit)) stack[size++] = 0;
        while (size > 0) {
            const std::uint32_t current = stack[--size];
            const BvhNode& node = nodes[current];
            if (node.is_leaf()) {
                for (std::uint32_t i = node.offset; i < node.offset + node.prim_count; ++i) {
                    Hit hit;
                    if (intersect_primitive(impl_->geometry, prim_indices[i], prepared, hit))
                        hits.push_back(hit);
                }
                continue;
            }
            for (const std::uint32_t child : {current + 1, node.offset}) {
                if (intersect_box(slab, nodes[child].bounds(), ray.tnear, ray.tfar, t_entry, t_exit))
                    stack[size++] = child;
            }
        }
    });
    std::sort(hits.begin() + static_cast<std::ptrdiff_t>(first), hits.end(),
              [](const Hit& a, const Hit& b) { return a.t < b.t || (a.t == b.t && a.prim < b.prim); });
}

namespace {

struct Vec3 {
    double x, y, z;
};
Vec3 operator-(const Vec3& a, const Vec3& b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
double dot(const Vec3& a, const Vec3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
Vec3 in_double(const Vec3f& a) {
    return {a.x, a.y, a.z};
}

// The barycentric weights (of v1, v2) of the point of triangle `tri` nearest to p: the Voronoi regions of
// its vertices, then of its edges, then its face (Ericson, Real-Time Collision Detection, 5.1.5). A
// degenerate triangle falls in a vertex's or an edge's region; a zero denominator there means two equal
// vertices, and either end is nearest.
std::pair<double, double> nearest_weights(const Triangle& tri, const Vec3& p) {
    const Vec3 a = in_double(tri.v0), b = in_double(tri.v1), c = in_double(tri.v2);
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return {0.0, 0.0};
    const Vec3 bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return {1.0, 0.0};
    const auto ratio = [](double n, double d) { return d == 0.0 ? 0.0 : n / d; };
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return {ratio(d1, d1 - d3), 0.0};
    const Vec3 cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return {0.0, 1.0};
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return {0.0, ratio(d2, d2 - d6)};
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
        const double w = ratio(d4 - d3, (d4 - d3) + (d5 - d6));
        return {1.0 - w, w};
    }
    const double sum = va + vb + vc;
    return {vb / sum, vc / sum};
}

// The nearest point of primitive `prim` to p, and its squared distance in double.
NearestPoint nearest_on(const Geometry& geometry, std::uint32_t prim, const Vec3& p, double& distance2) {
    NearestPoint nearest;
    nearest.prim = static_cast<std::int32_t>(prim);
    Vec3 q;
    if (prim < geometry.triangles.size()) {
        const Triangle& tri = geometry.triangles[prim];
        const auto [u, v] = nearest_weights(tri, p);
        const Vec3 a = in_double(tri.v0), b = in_double(tri.v1), c = in_double(tri.v2);
        q = {a.x + u * (b.x - a.x) + v * (c.x - a.x), a.y + u * (b.y - a.y) + v * (c.y - a.y),
             a.z + u * (b.z - a.z) + v * (c.z - a.z)};
        nearest.u = static_cast<float>(u), nearest.v = static_cast<float>(v);
    } else {
        const Sphere& sphere = geometry.spheres[prim - geometry.triangles.size()];
        const Vec3 centre = in_double(sphere.center), d = p - centre;
        const double length = std::sqrt(dot(d, d));
        const double scale = length > 0.0 ? std::max(0.0, static_cast<double>(sphere.radius)) / length : 0.0;
        q = {centre.x + scale * d.x, centre.y + scale * d.y, centre.z + scale * d.z};
    }
    const Vec3 e = p - q;
    distance2 = dot(e, e);
    nearest.point = {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z)};
    nearest.distance = static_cast<float>(std::sqrt(distance2));
    return nearest;
}

// The squared distance from p to the box, 0 inside.
double box_distance2(const Box3f& box, const Vec3& p) {
    double sum = 0.0;
    for (int axis = 0; axis < 3; ++axis) {
        const double x = axis == 0 ? p.x : (axis == 1 ? p.y : p.z);
        const double outside = std::max({static_cast<double>(box.lo[axis]) - x, 0.0, x - box.hi[axis]});
        sum += outside * outside;
    }
    return sum;
}

}  // namespace

NearestPoint GeometryQueries::nearest_point(const Vec3f& point) const {
    const std::vector<BvhNode>& nodes = impl_->bvh.nodes();
    const std::vector<std::uint32_t>& prim_indices = impl_->bvh.prim_indices();
    NearestPoint best;
    if (nodes.empty()) return best;
    const Vec3 p = in_double(point);
    double best2 = std::numeric_limits<double>::infinity();
    // Nodes by the distance to their box: the nearer child is taken first, a node no nearer than the best
    // point found is skipped.
    struct Entry {
        std::uint32_t node;
        double distance2;
    };
    std::array<Entry, BvhAccel::kMaxDepth + 2> stack;
    std::size_t size = 0;
    stack[size++] = {0, box_distance2(nodes[0].bounds(), p)};
    while (size > 0) {
        const Entry entry = stack[--size];
        if (entry.distance2 > best2) continue;
        const BvhNode& node = nodes[entry.node];
        if (node.is_leaf()) {
            for (std::uint32_t i = node.offset; i < node.offset + node.prim_count; ++i) {
                double distance2;
                const NearestPoint candidate = nearest_on(impl_->geometry, prim_indices[i], p, distance2);
                if (distance2 < best2 || (distance2 == best2 && candidate.prim < best.prim))
                    best = candidate, best2 = distance2;
            }
            continue;
        }
        Entry near{entry.node + 1, box_distance2(nodes[entry.node + 1].bounds(), p)};
        Entry far{node.offset, box_distance2(nodes[node.offset].bounds(), p)};
        if (far.distance2 < near.distance2) std::swap(near, far);
        if (far.distance2 <= best2) stack[size++] = far;
        if (near.distance2 <= best2) stack[size++] = near;
    }
    return best;
}

}  // namespace lancer
