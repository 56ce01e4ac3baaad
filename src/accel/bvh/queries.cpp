#include "lancer/queries.hpp"

#include <algorithm>
#include <array>

#include "accel/bvh/bvh.hpp"
#include "accel/primitive_test.hpp"

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

}  // namespace lancer
