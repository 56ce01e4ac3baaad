#include "lancer/queries.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/bvh_wide_walk.hpp"
#include "accel/bvh/nearest_point.hpp"
#include "accel/bvh/queries_impl.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/simd_float.hpp"
#include "core/ray_conditioning.hpp"

namespace lancer {

GeometryQueries::GeometryQueries(const Geometry& geometry, TriangleTest test)
    : impl_(std::make_unique<Impl>()) {
    impl_->test = test;
    impl_->own.build(geometry, build_options(test));
    impl_->scene = &impl_->own;
    impl_->binary = &impl_->own;
}

GeometryQueries::GeometryQueries(const Accel& accel, const Geometry& geometry, TriangleTest test)
    : impl_(std::make_unique<Impl>()) {
    impl_->test = test;
    // A packet structure traces its single-ray structure's tree as it is: that tree is the one to walk.
    const ExportedLayout layout = accel.exported_layout();
    const Accel& tree = layout.single_ray != nullptr ? *layout.single_ray : accel;
    impl_->scene = &accel;
    impl_->binary = layout.bvh;
    impl_->bvh4 = dynamic_cast<const Bvh4Accel*>(&tree);
    impl_->bvh8 = dynamic_cast<const Bvh8Accel*>(&tree);
    impl_->walks_accel = impl_->binary != nullptr || impl_->bvh4 != nullptr || impl_->bvh8 != nullptr;
    if (!impl_->walks_accel) {
        impl_->own.build(geometry, build_options(test));
        impl_->scene = &impl_->own;
        impl_->binary = &impl_->own;
    }
}

GeometryQueries::~GeometryQueries() = default;

bool GeometryQueries::walks_accel() const {
    return impl_->walks_accel;
}

namespace {

// Every primitive the ray hits, by the binary tree: every node whose box the ray crosses within [tnear,
// tfar], in any order. Both children of a node may wait, so the stack holds at most one node per level and
// the root.
template <class TriangleTestT, class OnHit>
void binary_hits(const BvhAccel& bvh, const Geometry& geometry, const PreparedRay<TriangleTestT>& prepared,
                 OnHit&& on_hit) {
    const HugePageVector<BvhNode>& nodes = bvh.nodes();
    const auto& prim_indices = bvh.prim_indices();
    const Ray& ray = prepared.ray;
    const SlabRay slab(ray);
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
                if (intersect_primitive(geometry, prim_indices[i], prepared, hit)) on_hit(hit);
            }
            continue;
        }
        for (const std::uint32_t child : {current + 1, node.offset}) {
            if (intersect_box(slab, nodes[child].bounds(), ray.tnear, ray.tfar, t_entry, t_exit))
                stack[size++] = child;
        }
    }
}

// The binary tree's nearest point: nodes by the distance to their box, the nearer child first, a node no
// nearer than the best point found skipped.
NearestPoint binary_nearest(const BvhAccel& bvh, nearest::Search& search) {
    const HugePageVector<BvhNode>& nodes = bvh.nodes();
    const auto& prim_indices = bvh.prim_indices();
    // The squared distance from p to the box, 0 inside.
    const auto box_distance2 = [&](const Box3f& box) {
        double sum = 0.0;
        for (int axis = 0; axis < 3; ++axis) {
            const double x = axis == 0 ? search.p.x : (axis == 1 ? search.p.y : search.p.z);
            const double outside = std::max({static_cast<double>(box.lo[axis]) - x, 0.0, x - box.hi[axis]});
            sum += outside * outside;
        }
        return sum;
    };
    struct Entry {
        std::uint32_t node;
        double distance2;
    };
    std::array<Entry, BvhAccel::kMaxDepth + 2> stack;
    std::size_t size = 0;
    stack[size++] = {0, box_distance2(nodes[0].bounds())};
    while (size > 0) {
        const Entry entry = stack[--size];
        if (entry.distance2 > search.best2) continue;
        const BvhNode& node = nodes[entry.node];
        if (node.is_leaf()) {
            for (std::uint32_t i = node.offset; i < node.offset + node.prim_count; ++i)
                search.primitive(prim_indices[i]);
            continue;
        }
        Entry near{entry.node + 1, box_distance2(nodes[entry.node + 1].bounds())};
        Entry far{node.offset, box_distance2(nodes[node.offset].bounds())};
        if (far.distance2 < near.distance2) std::swap(near, far);
        if (far.distance2 <= search.best2) stack[size++] = far;
        if (near.distance2 <= search.best2) stack[size++] = near;
    }
    return search.best;
}

// A lower bound of the squared distance from p to each child box of `node`, in float: the rounding of its
// five operations (at most 5 units of 2^-24, relative) is taken off by kShrink, so that the bound never
// exceeds the double distance to any point in the box. Bit i of the result: child i is no farther than
// `limit` (an empty slot, whose inverted box gives an infinite bound, never is).
constexpr float kShrink = 1.0f - 0x1p-20f;

#if defined(__AVX2__) || defined(__SSE4_1__)
template <class Ops, int W>
unsigned child_bounds_simd(const WideBvhNode<W>& node, const Vec3f& p, float limit, float (&bound)[W]) {
    using Float = typename Ops::Float;
    const Float zero = Ops::broadcast(0.0f);
    Float sum = zero;
    for (int axis = 0; axis < 3; ++axis) {
        const Float x = Ops::broadcast(p[axis]);
        const Float outside =
            Ops::max(Ops::max(Ops::sub(Ops::load(node.bounds[WideBvhNode<W>::kLo][axis]), x),
                              Ops::sub(x, Ops::load(node.bounds[WideBvhNode<W>::kHi][axis]))),
                     zero);
        sum = Ops::add(sum, Ops::mul(outside, outside));
    }
    sum = Ops::mul(sum, Ops::broadcast(kShrink));
    Ops::store(bound, sum);
    return Ops::bits(Ops::less_equal(sum, Ops::broadcast(limit)));
}
#endif

template <int W>
unsigned child_bounds(const WideBvhNode<W>& node, const Vec3f& p, float limit, float (&bound)[W]) {
#if defined(__AVX2__)
    if constexpr (W == 8) return child_bounds_simd<simd::Avx2>(node, p, limit, bound);
#endif
#if defined(__SSE4_1__)
    if constexpr (W == 4) return child_bounds_simd<simd::Sse4>(node, p, limit, bound);
#endif
    unsigned mask = 0;
    for (int slot = 0; slot < W; ++slot) {
        float sum = 0.0f;
        for (int axis = 0; axis < 3; ++axis) {
            const float outside = std::max(std::max(node.bounds[WideBvhNode<W>::kLo][axis][slot] - p[axis],
                                                    p[axis] - node.bounds[WideBvhNode<W>::kHi][axis][slot]),
                                           0.0f);
            sum += outside * outside;
        }
        bound[slot] = sum * kShrink;
        if (bound[slot] <= limit) mask |= 1u << slot;
    }
    return mask;
}

// The wide tree's nearest point: the children of a node bounded at once, pushed farthest first so that
// the nearest is taken next (the first leaf reached is the greedy descent's, whose point bounds the rest),
// and a leaf's triangles four at a time in double (nearest::Search::block).
template <int W>
NearestPoint wide_nearest(const WideBvhAccel<W>& bvh, const Vec3f& point, nearest::Search& search) {
    const auto& nodes = bvh.nodes();
    const auto& blocks = bvh.blocks();
    struct Entry {
        float bound;
        std::uint32_t child, prim_count;
    };
    std::array<Entry, (W - 1) * BvhAccel::kMaxDepth + 1> stack;
    std::size_t size = 0;
    const WideBvhNode<W>* node = &nodes[0];
    while (true) {
        alignas(32) float bound[W];
        std::array<int, W> order;
        const int count =
            order_by_entry<W>(child_bounds(*node, point, search.float_limit(), bound), bound, order);
        for (int k = count - 1; k >= 0; --k) {
            const auto slot = static_cast<std::size_t>(order[static_cast<std::size_t>(k)]);
            stack[size++] = {bound[slot], node->child[slot], node->prim_count[slot]};
        }
        while (true) {
            if (size == 0) return search.best;
            const Entry entry = stack[--size];
            if (static_cast<double>(entry.bound) > search.best2) continue;
            if (entry.prim_count == 0) {
                node = &nodes[entry.child];
                break;
            }
            const LeafSpan span = leaf_span<W>(entry.child, entry.prim_count);
            for (std::uint32_t b = span.first; b < span.end; ++b)
                search.block(blocks[b]);
        }
    }
}

// The float point from which wide_nearest bounds the child boxes: p, or, where p lies more than 2^60 from
// the scene's centre on some axis (its float squared distances could overflow; p's own coordinates could,
// in a scene scaled up), p moved onto a box that holds every node's box, the scene's box grown by its
// largest side and coordinate (beyond the geometric tolerance). The distance from there to a box inside is
// no larger than from p (the projection on a convex set moves no point away from any point of it), so the
// bounds stay lower bounds: the same answer, with less pruning.
Vec3f bounding_point(const Box3f& scene_bounds, const Vec3d& p) {
    const Vec3f centre = scene_bounds.center();
    const double reach[3] = {p.x - centre.x, p.y - centre.y, p.z - centre.z};
    if (std::fabs(reach[0]) <= 0x1p60 && std::fabs(reach[1]) <= 0x1p60 && std::fabs(reach[2]) <= 0x1p60)
        return {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
    const float margin = max_component(scene_bounds.extent()) +
                         std::fmax(max_component(abs(scene_bounds.lo)), max_component(abs(scene_bounds.hi)));
    const Box3f box = scene_bounds.grown(margin);
    return {static_cast<float>(std::clamp(p.x, double(box.lo.x), double(box.hi.x))),
            static_cast<float>(std::clamp(p.y, double(box.lo.y), double(box.hi.y))),
            static_cast<float>(std::clamp(p.z, double(box.lo.z), double(box.hi.z)))};
}

}  // namespace

template <class OnHit>
void GeometryQueries::Impl::each_hit(const Ray& traced, OnHit&& on_hit) const {
    const Geometry& geometry = scene->built_geometry();
    dispatch_policies(test, false, [&]<class TriangleTestT, bool>() {
        const PreparedRay<TriangleTestT> prepared(traced);
        if (bvh8 != nullptr) {
            wide_walk::all_hits(bvh8->nodes(), bvh8->blocks(), geometry, prepared, on_hit);
        } else if (bvh4 != nullptr) {
            wide_walk::all_hits(bvh4->nodes(), bvh4->blocks(), geometry, prepared, on_hit);
        } else {
            binary_hits(*binary, geometry, prepared, on_hit);
        }
    });
}

void GeometryQueries::all_hits(const Ray& ray, std::vector<Hit>& hits) const {
    const Accel& scene = *impl_->scene;
    if (!is_valid(ray) || scene.built_geometry().size() == 0) return;
    const std::size_t first = hits.size();
    impl_->each_caller_hit(ray, [&](const Hit& hit) { hits.push_back(hit); });
    const auto begin = hits.begin() + static_cast<std::ptrdiff_t>(first);
    std::sort(begin, hits.end(),
              [](const Hit& a, const Hit& b) { return a.t < b.t || (a.t == b.t && a.prim < b.prim); });
    // A tree with spatial splits holds a primitive in several leaves: one hit each.
    hits.erase(std::unique(begin, hits.end(),
                           [](const Hit& a, const Hit& b) { return a.prim == b.prim && a.t == b.t; }),
               hits.end());
}

template <class OnHit>
void GeometryQueries::Impl::each_caller_hit(const Ray& ray, OnHit&& on_hit) const {
    const ConditionedRays conditioned =
        condition_rays(std::span(&ray, 1), scene->bounds(), scene->scale_exponent());
    if (conditioned.rays.empty()) {
        each_hit(ray, on_hit);
        return;
    }
    each_hit(conditioned.rays[0], [&](Hit hit) {
        if (const std::optional<float> t = restore_t(hit.t, conditioned.how[0], ray)) {
            hit.t = *t;
            on_hit(hit);
        }
    });
}

std::uint32_t GeometryQueries::Impl::walked_crossings(const Ray& ray, std::vector<float>& times) const {
    times.clear();
    each_caller_hit(ray, [&](const Hit& hit) { times.push_back(hit.t); });
    return queries_detail::distinct_count(times);
}

NearestPoint GeometryQueries::nearest_point(const Vec3f& point) const {
    const Accel& scene = *impl_->scene;
    const Geometry& geometry = scene.built_geometry();
    const int exponent = scene.scale_exponent();
    // The point at the scene's scale, exactly in double whatever the exponent.
    const Vec3d p(std::ldexp(double(point.x), exponent), std::ldexp(double(point.y), exponent),
                  std::ldexp(double(point.z), exponent));
    nearest::Search search(geometry, p);
    if (geometry.size() == 0) return search.best;
    NearestPoint nearest;
    if (impl_->bvh8 != nullptr) {
        nearest = wide_nearest(*impl_->bvh8, bounding_point(scene.built_bounds(), p), search);
    } else if (impl_->bvh4 != nullptr) {
        nearest = wide_nearest(*impl_->bvh4, bounding_point(scene.built_bounds(), p), search);
    } else {
        nearest = binary_nearest(*impl_->binary, search);
    }
    // The winner again in double, scaled back before its one rounding.
    return exponent == 0 || nearest.prim < 0 ? nearest
                                             : nearest::nearest_on_scaled(geometry, nearest, p, -exponent);
}

}  // namespace lancer
