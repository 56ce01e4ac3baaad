// Kernel throughput: one triangle test (both variants), one slab test, one sphere test, per call; the ray
// conditioning scan of a batch, per ray; one node step of each walk (BVH inner node, octree node, kd-tree
// node, Plücker leaf-to-leaf step) and the Plücker exit face alone. Inputs are random but fixed (seeded)
// and visited in a shuffled order, and half of the rays hit, so branch prediction is not flattered.
// docs/accel/parallel-build.md has the figures.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "accel/kdtree.hpp"
#include "accel/octree.hpp"
#include "accel/plucker/plucker.hpp"
#include "accel/plucker/walk.hpp"
#include "core/intersect.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/generate.hpp"

namespace lancer {
namespace {

constexpr std::size_t kCount = 4096;

struct Inputs {
    std::vector<Ray> rays;
    std::vector<Triangle> triangles;
    std::vector<Box3f> boxes;
};

const Inputs& inputs() {
    static const Inputs data = [] {
        std::mt19937 rng(42);
        std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
        auto point = [&] { return Vec3f(coordinate(rng), coordinate(rng), coordinate(rng)); };
        Inputs made;
        for (std::size_t i = 0; i < kCount; ++i) {
            const Triangle tri{point(), point(), point()};
            const Vec3f origin = point() * 4.0f;
            const Vec3f target = i % 2 ? tri.bounds().center() : point() * 2.0f;
            made.triangles.push_back(tri);
            made.boxes.push_back(tri.bounds());
            made.rays.push_back({origin, target - origin, 0.0f, kInfinity});
        }
        return made;
    }();
    return data;
}

template <class TriangleTestT>
void BM_Triangle(benchmark::State& state) {
    const Inputs& in = inputs();
    std::vector<typename TriangleTestT::RayData> prepared;
    for (const Ray& ray : in.rays)
        prepared.emplace_back(ray);
    std::size_t i = 0;
    for (auto _ : state) {
        TriangleHit hit;
        benchmark::DoNotOptimize(
            TriangleTestT::intersect(prepared[i], in.triangles[i], 0.0f, kInfinity, hit));
        benchmark::DoNotOptimize(hit);
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Triangle<MollerTrumbore>)->Name("triangle/moller_trumbore");
BENCHMARK(BM_Triangle<Watertight>)->Name("triangle/watertight");

void BM_Box(benchmark::State& state) {
    const Inputs& in = inputs();
    std::vector<SlabRay> prepared;
    for (const Ray& ray : in.rays)
        prepared.emplace_back(ray);
    std::size_t i = 0;
    for (auto _ : state) {
        float entry, exit;
        benchmark::DoNotOptimize(intersect_box(prepared[i], in.boxes[i], 0.0f, kInfinity, entry, exit));
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Box)->Name("box/slab");

// What Accel::intersect adds to every batch (src/core/ray_conditioning.hpp): the scan of a batch of ordinary
// rays, none of which needs conditioning. Per ray; compare with a structure's ns per ray.
void BM_ConditionOrdinaryBatch(benchmark::State& state) {
    const Inputs& in = inputs();
    const Box3f scene{Vec3f(-1.0f), Vec3f(1.0f)};
    for (auto _ : state)
        benchmark::DoNotOptimize(condition_rays(in.rays, scene));
    state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kCount));
}
BENCHMARK(BM_ConditionOrdinaryBatch)->Name("batch/condition_rays");

void BM_Sphere(benchmark::State& state) {
    const Inputs& in = inputs();
    std::size_t i = 0;
    for (auto _ : state) {
        TriangleHit hit;
        const Sphere sphere{in.boxes[i].center(), 0.5f, 0};
        benchmark::DoNotOptimize(intersect_sphere(in.rays[i], sphere, 0.0f, kInfinity, hit));
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Sphere)->Name("sphere/haines");

// The structures the node steps read: a scene of about 100k triangles (an icosphere and a triangle soup), so
// that the nodes do not all sit in L1, and rays crossing its box in every direction.
struct Walks {
    std::vector<Triangle> triangles;
    std::vector<Ray> rays;
    BvhAccel bvh;
    KdTreeAccel kdtree;
    PluckerAccel plucker;
    Octree octree;
};

const Walks& walks() {
    static const Walks* data = [] {
        auto* made = new Walks;
        made->triangles = make_icosphere(6, {0, 0, 0}, 1.0f).triangles();
        std::mt19937 rng(7);
        std::uniform_real_distribution<float> coordinate(-1.5f, 1.5f);
        auto point = [&] { return Vec3f(coordinate(rng), coordinate(rng), coordinate(rng)); };
        for (int i = 0; i < 20000; ++i) {
            const Vec3f base = point();
            made->triangles.push_back({base, base + 0.05f * point(), base + 0.05f * point()});
        }
        for (std::size_t i = 0; i < kCount; ++i) {
            const Vec3f origin = point() * 2.0f;
            made->rays.push_back({origin, point() - origin, 0.0f, kInfinity});
        }
        const Geometry geometry{made->triangles, {}};
        const BuildOptions options;
        made->bvh.build(geometry, options);
        made->kdtree.build(geometry, options);
        made->plucker.build(geometry, options);
        made->octree = build_octree(geometry, options.group<OctreeOptions>());
        return made;
    }();
    return *data;
}

// Indices 0 .. count - 1 in a fixed random order: consecutive iterations read unrelated inputs.
std::vector<std::uint32_t> shuffled(std::size_t count) {
    std::vector<std::uint32_t> order(count);
    for (std::uint32_t i = 0; i < count; ++i)
        order[i] = i;
    std::shuffle(order.begin(), order.end(), std::mt19937(99));
    return order;
}

// EXIT-FACE alone (Portalez & Duguet 2016, section 4.2.1, equations 4-8): the exit vertex of a random cell, a
// ray from a random point inside it in a random direction, 6 products and a table lookup. Each of the three
// exit faces comes out about as often as the others.
void BM_PluckerExitFace(benchmark::State& state) {
    struct Input {
        plucker::WalkRay ray;
        Vec3f to_exit_vertex;
    };
    std::vector<Input> inputs;
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f), signed_unit(-1.0f, 1.0f);
    const OctreeCube cube{Vec3f(0.0f), 1.0f};
    for (std::size_t i = 0; i < kCount; ++i) {
        const Vec3f lo(unit(rng), unit(rng), unit(rng));
        const float size = 0.01f + 0.1f * unit(rng);
        const Vec3f origin = lo + size * Vec3f(unit(rng), unit(rng), unit(rng));
        const Ray ray{origin, {signed_unit(rng), signed_unit(rng), signed_unit(rng)}, 0.0f, kInfinity};
        const plucker::WalkRay walk_ray(ray, cube, plucker::kTables);
        Vec3f vertex;
        for (int axis = 0; axis < 3; ++axis)
            vertex[axis] = lo[axis] + (walk_ray.up(axis) ? size : 0.0f);
        inputs.push_back({walk_ray, vertex - origin});
    }
    const std::vector<std::uint32_t> order = shuffled(kCount);
    std::size_t i = 0;
    for (auto _ : state) {
        const Input& input = inputs[order[i]];
        benchmark::DoNotOptimize(plucker::exit_face(input.ray, input.to_exit_vertex));
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_PluckerExitFace)->Name("step/plucker_exit_face");

// One Plücker leaf-to-leaf step (Walker::advance: EXIT-FACE, sub-face when the face has four neighbours,
// NEIGHBOR lookup) from walk states met along real walks through the balanced, stored-box layout.
void BM_PluckerLeafStep(benchmark::State& state) {
    const Walks& scene = walks();
    const plucker::PluckerLayout& layout = scene.plucker.layout();
    const plucker::PluckerView view = plucker::view_of(layout);
    const plucker::Walker<true, true> walker(view, plucker::kTables);
    using State = plucker::Walker<true, true>::State;
    TraversalCounters unused;
    plucker::CellCounter<false> steps{unused};
    std::vector<State> states;
    for (std::size_t r = 0; states.size() < kCount && r < scene.rays.size(); ++r) {
        State walk_state;
        if (!walker.enter(scene.rays[r], walk_state)) continue;
        do {
            states.push_back(walk_state);
        } while (states.size() < kCount &&
                 walker.advance(walk_state, walker.exit(walk_state), kInfinity, steps));
    }
    const std::vector<std::uint32_t> order = shuffled(states.size());
    std::size_t i = 0;
    for (auto _ : state) {
        State walk_state = states[order[i]];
        benchmark::DoNotOptimize(walker.advance(walk_state, walker.exit(walk_state), kInfinity, steps));
        benchmark::DoNotOptimize(walk_state.address);
        i = (i + 1) % states.size();
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["cells_kB"] =
        static_cast<double>(layout.cells.size() * 4 + layout.boxes.size() * 36) / 1e3;
}
BENCHMARK(BM_PluckerLeafStep)->Name("step/plucker_leaf_to_leaf");

// One BVH inner node step (bvh/bvh.cpp's traverse): the slab tests of both children and the near-first order,
// on random (inner node, ray) pairs.
void BM_BvhInnerStep(benchmark::State& state) {
    const Walks& scene = walks();
    const HugePageVector<BvhNode>& nodes = scene.bvh.nodes();
    std::vector<std::uint32_t> inner;
    for (std::uint32_t n = 0; n < nodes.size(); ++n) {
        if (!nodes[n].is_leaf()) inner.push_back(n);
    }
    std::mt19937 rng(3);
    std::vector<std::pair<std::uint32_t, SlabRay>> inputs;
    for (std::size_t i = 0; i < kCount; ++i)
        inputs.emplace_back(inner[rng() % inner.size()], SlabRay(scene.rays[i]));
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& [node, slab] = inputs[i];
        const std::uint32_t first = node + 1, second = nodes[node].offset;
        float first_entry, second_entry, exit;
        const bool hit_first = intersect_box(slab, nodes[first].bounds(), 0.0f, kInfinity, first_entry, exit);
        const bool hit_second =
            intersect_box(slab, nodes[second].bounds(), 0.0f, kInfinity, second_entry, exit);
        const bool first_is_near = first_entry <= second_entry;
        const std::uint32_t next =
            hit_first && hit_second ? (first_is_near ? first : second) : (hit_first ? first : second);
        benchmark::DoNotOptimize(next);
        benchmark::DoNotOptimize(hit_first || hit_second);
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_BvhInnerStep)->Name("step/bvh_inner_node");

// One octree node step (Revelles et al. 2000, as octree.cpp walks it): the mid-plane parameters from the
// build's planes, the first child (tables 1-2) and the next sibling (table 3), on random (inner cell, ray)
// pairs with the cell's slab parameters t0, t1.
void BM_OctreeNodeStep(benchmark::State& state) {
    const Walks& scene = walks();
    const Octree& octree = scene.octree;
    std::vector<const OctreeCell*> inner;
    for (const OctreeCell& cell : octree.cells) {
        if (!cell.is_leaf()) inner.push_back(&cell);
    }
    struct Input {
        const OctreeCell* cell;
        Vec3f origin, inv_direction, t0, t1;
    };
    std::mt19937 rng(4);
    std::vector<Input> inputs;
    for (std::size_t i = 0; i < kCount; ++i) {
        const OctreeCell* cell = inner[rng() % inner.size()];
        const Box3f box = octree.cell_box(*cell);
        // A ray through the cell, in the mirrored frame (every component >= 0) that Revelles works in.
        Ray ray = scene.rays[i];
        ray.direction = abs(ray.direction);
        ray.origin = box.center() - ray.direction * (0.5f + 0.01f * static_cast<float>(rng() % 100));
        Input input{cell, ray.origin, SlabRay(ray).inv_direction, {}, {}};
        for (int axis = 0; axis < 3; ++axis) {
            input.t0[axis] = (box.lo[axis] - ray.origin[axis]) * input.inv_direction[axis];
            input.t1[axis] = (box.hi[axis] - ray.origin[axis]) * input.inv_direction[axis];
        }
        inputs.push_back(input);
    }
    std::size_t i = 0;
    for (auto _ : state) {
        const Input& input = inputs[i];
        const OctreeCell& cell = *input.cell;
        Vec3f tm;
        for (int axis = 0; axis < 3; ++axis) {
            const float mid = octree.cube.plane(axis, cell.level + 1, 2u * cell.coordinate(axis) + 1u);
            tm[axis] = (mid - input.origin[axis]) * input.inv_direction[axis];
        }
        const int first = revelles::first_child(input.t0, tm);
        benchmark::DoNotOptimize(cell.first_child + static_cast<std::uint32_t>(first));
        benchmark::DoNotOptimize(revelles::next_child(first, tm, input.t1));
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_OctreeNodeStep)->Name("step/octree_node");

// One kd-tree node step (kdtree.cpp's walk, pbrt-v3's three cases): the split parameter, the near and far
// children and the choice among near only, far only or both (far pushed), on random (inner node, ray,
// interval) pairs from the tree.
void BM_KdTreeNodeStep(benchmark::State& state) {
    const Walks& scene = walks();
    const KdTreeData& tree = scene.kdtree.tree();
    std::vector<std::uint32_t> inner;
    for (std::uint32_t n = 0; n < tree.nodes.size(); ++n) {
        if (!tree.nodes[n].is_leaf()) inner.push_back(n);
    }
    struct Input {
        std::uint32_t node;
        Vec3f origin, inv_direction;
        float tmin, tmax;
    };
    std::mt19937 rng(8);
    std::vector<Input> inputs;
    for (std::size_t i = 0; i < kCount; ++i) {
        const Ray& ray = scene.rays[i];
        float tmin, tmax;
        if (!intersect_box(SlabRay(ray), tree.bounds, 0.0f, kInfinity, tmin, tmax)) tmin = 0.0f, tmax = 1.0f;
        const float a = tmin + (tmax - tmin) * static_cast<float>(rng() % 1000) / 1000.0f;
        const float b = tmin + (tmax - tmin) * static_cast<float>(rng() % 1000) / 1000.0f;
        inputs.push_back({inner[rng() % inner.size()], ray.origin, SlabRay(ray).inv_direction, std::min(a, b),
                          std::max(a, b)});
    }
    struct Far {
        std::uint32_t node;
        float tmin, tmax;
    };
    std::array<Far, 2> stack{};
    std::size_t i = 0;
    for (auto _ : state) {
        const Input& input = inputs[i];
        const KdNode& node = tree.nodes[input.node];
        const int axis = node.axis();
        const float t_split = (node.split() - input.origin[axis]) * input.inv_direction[axis];
        const bool below_first = input.inv_direction[axis] > 0.0f;
        const std::uint32_t below = input.node + 1, above = node.above_child();
        const std::uint32_t first = below_first ? below : above, second = below_first ? above : below;
        std::uint32_t next;
        float tmax = input.tmax;
        if (t_split < input.tmin) {
            next = second;
        } else if (t_split > input.tmax) {
            next = first;
        } else {
            stack[i & 1] = {second, t_split, tmax};
            next = first;
            tmax = t_split;
        }
        benchmark::DoNotOptimize(next);
        benchmark::DoNotOptimize(tmax);
        benchmark::DoNotOptimize(stack);
        i = (i + 1) % kCount;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_KdTreeNodeStep)->Name("step/kdtree_node");

}  // namespace
}  // namespace lancer
