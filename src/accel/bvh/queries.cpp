#include "lancer/queries.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <span>
#include <type_traits>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/bvh/bvh.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/bvh_wide_walk.hpp"
#include "accel/bvh/nearest_point.hpp"
#include "accel/crossing_grid.hpp"
#include "accel/primitive_intersect.hpp"
#include "accel/simd_float.hpp"
#include "core/host_device.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/parallel.hpp"

namespace lancer {

namespace {

// An array reused from call to call: grown when too small, never shrunk nor cleared, so that a call no larger
// than an earlier one writes into pages already faulted in, which fresh ones cost more than the work on
// them (docs/python.md, "Occupancy").
template <class T>
class ReusedArray {
  public:
    [[nodiscard]] std::span<T> first(std::size_t count) {
        if (count > capacity_) data_ = std::make_unique_for_overwrite<T[]>(count), capacity_ = count;
        return {data_.get(), count};
    }

  private:
    std::unique_ptr<T[]> data_;
    std::size_t capacity_ = 0;
};

// The distinct values of `times`, which it sorts.
std::uint32_t distinct_count(std::vector<float>& times) {
    std::sort(times.begin(), times.end());
    return static_cast<std::uint32_t>(std::unique(times.begin(), times.end()) - times.begin());
}

// A ray of count_crossings that tests a cell's primitives: its cell, its index among the origins, and its
// origin, moved with it by the sort so that the rays of a cell read theirs in turn: read through the index,
// each origin is a TLB and cache miss, which prefetching did not hide (docs/python.md, "Occupancy").
// Its origin as three floats, not a Vec3f, whose member initialisers made make_unique_for_overwrite zero the
// arrays (40 bytes a point, at every first call; docs/python.md, "Occupancy").
struct RayInCell {
    std::uint32_t cell;
    std::uint32_t index;
    float x, y, z;

    RayInCell() = default;
    RayInCell(std::uint32_t c, std::uint32_t i, const Vec3f& o) : cell(c), index(i), x(o.x), y(o.y), z(o.z) {}
    [[nodiscard]] Vec3f origin() const { return {x, y, z}; }
};
static_assert(sizeof(RayInCell) == 20 && std::is_trivially_default_constructible_v<RayInCell>);

// count_crossings' arrays, kept between calls: the rays that test a cell's primitives, in their order and by
// cell (a radix sort's two arrays), and the counts of the cells' digits.
struct CrossingBuffers {
    ReusedArray<RayInCell> rays, sorted;
    ReusedArray<std::uint32_t> digit_counts;
};

// The radix sort's digits: at most 2^11 values, so that the counts and the places they scatter to stay in
// the first-level cache.
constexpr int kMaxDigitBits = 11;

}  // namespace

// One of the trees below is walked: the structure's own (binary, bvh4's or bvh8's), or `own`. Either was
// built on `scene`'s built geometry, which is the caller's scaled by 2^scale_exponent
// (Accel::built_geometry): rays and points are conditioned and scaled as Accel::intersect's are, and answers
// mapped back. The structure is read at each query, so that its updates are followed.
struct GeometryQueries::Impl {
    TriangleTest test = TriangleTest::MollerTrumbore;
    BvhAccel own;  // built only for a structure that has no BVH
    const Accel* scene = nullptr;
    const BvhAccel* binary = nullptr;
    const Bvh4Accel* bvh4 = nullptr;
    const Bvh8Accel* bvh8 = nullptr;
    bool walks_accel = false;

    // count_crossings' grids, and its arrays, kept between calls (docs/python.md, "Occupancy").
    CrossingGrids grids;
    std::mutex buffers_mutex;
    CrossingBuffers buffers;

    // on_hit(hit) for every hit of `traced`, a valid ray conditioned for `scene`, in no order.
    template <class OnHit>
    void each_hit(const Ray& traced, OnHit&& on_hit) const;
    // on_hit(hit) for every hit of `ray`, a valid ray as the caller gave it, in no order: conditioned and
    // walked as each_hit, each t mapped back to the caller's parametrisation as Accel::intersect maps its
    // hits (one beyond the float range is none).
    template <class OnHit>
    void each_caller_hit(const Ray& ray, OnHit&& on_hit) const;
    // The crossings of a valid ray (count_crossings) by a walk of the tree, its hits as all_hits gives them;
    // `times` is scratch.
    std::uint32_t walked_crossings(const Ray& ray, std::vector<float>& times) const;
};

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
    const std::vector<BvhNode>& nodes = bvh.nodes();
    const std::vector<std::uint32_t>& prim_indices = bvh.prim_indices();
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
    const std::vector<BvhNode>& nodes = bvh.nodes();
    const std::vector<std::uint32_t>& prim_indices = bvh.prim_indices();
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
            const std::uint32_t last = entry.child + block_count(entry.prim_count, W);
            for (std::uint32_t b = entry.child; b < last; ++b)
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
    return distinct_count(times);
}

void GeometryQueries::count_crossings(const Vec3f& direction, std::span<const Vec3f> origins,
                                      std::span<std::uint32_t> crossings, int threads) const {
    const Accel& scene = *impl_->scene;
    const Geometry& geometry = scene.built_geometry();
    const std::size_t count = origins.size();
    constexpr std::size_t kRaysPerTask = 1024;
    // The rays share their direction and interval [0, inf]: a direction that leaves them invalid hits
    // nothing.
    if (geometry.size() == 0 || !is_valid(Ray{Vec3f(0.0f), direction, 0.0f, kInfinity})) {
        std::fill_n(crossings.begin(), count, 0u);
        return;
    }
    // The grid costs a pass over the triangles and their cells; a ray through it a few block tests, where a
    // tree walk costs several times that: it pays from about one ray per four primitives. A scene scaled to
    // the structures' range (Accel::scale_exponent), or a direction scaled to the kernels' (a component
    // beyond [2^-32, 2^32]), conditions every ray: those walk the tree. Cells are numbered below 2^32 - 1 (at
    // most about 1.5 a primitive, and primitives below 2^31).
    const FarOriginFrame frame(scene.bounds());
    if (scene.scale_exponent() != 0 || 4 * count < geometry.size() ||
        count > std::numeric_limits<std::uint32_t>::max() ||
        may_need_conditioning(Ray{frame.centre(), direction, 0.0f, kInfinity}, frame)) {
        parallel_for(count, kRaysPerTask, threads, [&](std::size_t first, std::size_t last) {
            std::vector<float> task_times;
            for (std::size_t i = first; i < last; ++i) {
                const Ray ray{origins[i], direction, 0.0f, kInfinity};
                crossings[i] = is_finite(ray.origin) ? impl_->walked_crossings(ray, task_times) : 0u;
            }
        });
        return;
    }
    const std::shared_ptr<const CrossingGrid> grid = impl_->grids.grid(
        geometry, scene.built_bounds(), direction, geometry.size() / 2, threads, scene.geometry_version_);
    // The arrays of the last call, unless another thread's call holds them.
    std::unique_lock<std::mutex> buffers_lock(impl_->buffers_mutex, std::try_to_lock);
    CrossingBuffers own_buffers;
    CrossingBuffers& buffers = buffers_lock.owns_lock() ? impl_->buffers : own_buffers;

    // First pass, in kRuns runs of consecutive rays: the rays that test a cell's primitives are written out,
    // each run's from its own place on; the others get their answer now: a ray from a non-finite origin
    // (invalid) or one whose cell lists nothing crosses nothing, and one from far away, which conditioning
    // moves, walks the tree (the direction is valid and needs none: of a ray, only the origin is checked).
    // The cells' first digits are counted on the way for the radix sort.
    constexpr std::size_t kRuns = 4;
    const std::size_t run = std::max<std::size_t>((count + kRuns - 1) / kRuns, 1);
    const int cell_bits = static_cast<int>(std::bit_width(grid->cell_count() - 1));
    const int passes = std::max(1, (cell_bits + kMaxDigitBits - 1) / kMaxDigitBits);
    const int digit_bits = std::max(1, (cell_bits + passes - 1) / passes);
    const std::size_t digits = std::size_t{1} << digit_bits;
    const std::span<RayInCell> listed_rays = buffers.rays.first(count), sorted = buffers.sorted.first(count);
    const std::span<std::uint32_t> digit_counts = buffers.digit_counts.first(kRuns * passes * digits);
    std::fill(digit_counts.begin(), digit_counts.end(), 0u);
    std::array<std::size_t, kRuns> run_rays{};
    parallel_for(count, run, threads, [&](std::size_t first, std::size_t last) {
        const std::size_t r = first / run;
        std::uint32_t* counts = digit_counts.data() + r * passes * digits;
        std::size_t written = first;
        std::vector<float> task_times;
        const auto one = [&](std::size_t i) {
            const Vec3f& origin = origins[i];
            if (!is_finite(origin)) {
                crossings[i] = 0;
            } else if (frame.is_far(origin)) {
                crossings[i] = impl_->walked_crossings({origin, direction, 0.0f, kInfinity}, task_times);
            } else if (const std::size_t cell = grid->cell_of(origin); !grid->lists_any(cell)) {
                crossings[i] = 0;
            } else {
                listed_rays[written++] = {static_cast<std::uint32_t>(cell), static_cast<std::uint32_t>(i),
                                          origin};
                ++counts[cell & (digits - 1)];
            }
        };
        // Eight origins at a time where all are finite and near (the grid's vector cells), without a branch
        // on whether each is listed: every ray is written at the next place, which only a listed one keeps,
        // and every answer set to 0, which the listed ones' tests overwrite. Taken ray by ray, that branch
        // went either way at random (41% of the bunny's rays are listed) and mispredicted (docs/python.md,
        // "Occupancy").
        const Vec3f centre = frame.centre();
        const float limit = frame.far_limit();
        std::size_t i = first;
        for (; i + 8 <= last; i += 8) {
            std::array<std::uint32_t, 8> cells;
            const int listed = grid->listed_cells(&origins[i], centre, limit, cells.data());
            if (listed < 0) {
                for (std::size_t j = i; j < i + 8; ++j)
                    one(j);
                continue;
            }
            for (std::size_t j = 0; j < 8; ++j) {
                const std::uint32_t cell = cells[j], kept = (static_cast<unsigned>(listed) >> j) & 1u;
                crossings[i + j] = 0;
                listed_rays[written] = {cell, static_cast<std::uint32_t>(i + j), origins[i + j]};
                written += kept;
                counts[cell & (digits - 1)] += kept;
            }
        }
        for (; i < last; ++i)
            one(i);
        run_rays[r] = written - first;
    });
    // An LSD radix sort by cell, stable, so that a cell's rays stay in the order of their index. Each pass
    // in kRuns chunks on the threads, each chunk's rays scattered from its own places on, those of a digit
    // after the earlier chunks' (the first pass's chunks are the runs, whose digits it counted; a later
    // pass's are counted first): on one thread, the sort was a serial part of a call on two (docs/python.md,
    // "Occupancy").
    std::size_t listed = 0;
    for (const std::size_t n : run_rays)
        listed += n;
    std::span<RayInCell> from = listed_rays, to = sorted;
    std::array<std::size_t, kRuns> chunk_first{}, chunk_last{};
    for (std::size_t r = 0; r < kRuns; ++r)
        chunk_first[r] = r * run, chunk_last[r] = r * run + run_rays[r];
    std::vector<std::size_t> next(kRuns * digits);
    for (int pass = 0; pass < passes; ++pass) {
        const int shift = pass * digit_bits;
        const auto digit = [&](const RayInCell& ray) { return (ray.cell >> shift) & (digits - 1); };
        const auto counts_of = [&](std::size_t r) {
            return digit_counts.data() +
                   (r * static_cast<std::size_t>(passes) + static_cast<std::size_t>(pass)) * digits;
        };
        if (pass > 0) {
            const std::size_t chunk = (listed + kRuns - 1) / kRuns;
            for (std::size_t r = 0; r < kRuns; ++r)
                chunk_first[r] = std::min(r * chunk, listed),
                chunk_last[r] = std::min(r * chunk + chunk, listed);
            parallel_for(kRuns, 1, threads, [&](std::size_t first, std::size_t last) {
                for (std::size_t r = first; r < last; ++r) {
                    std::uint32_t* counts = counts_of(r);
                    for (std::size_t k = chunk_first[r]; k < chunk_last[r]; ++k)
                        ++counts[digit(from[k])];
                }
            });
        }
        std::size_t place = 0;
        for (std::size_t d = 0; d < digits; ++d) {
            for (std::size_t r = 0; r < kRuns; ++r)
                next[r * digits + d] = place, place += counts_of(r)[d];
        }
        parallel_for(kRuns, 1, threads, [&](std::size_t first, std::size_t last) {
            for (std::size_t r = first; r < last; ++r) {
                std::size_t* at = next.data() + r * digits;
                for (std::size_t k = chunk_first[r]; k < chunk_last[r]; ++k)
                    to[at[digit(from[k])]++] = from[k];
            }
        });
        std::swap(from, to);
    }
    const std::span<const RayInCell> by_cell = from.first(listed);
    const Geometry in_grid_order{grid->triangles(), geometry.spheres};
    // Cell by cell: its primitives gathered into blocks once for its rays (once per task that holds some of
    // them), each ray tested against them by bvh8's block kernel, the tree's own bits, its answer's place
    // prefetched a few rays ahead (each is a cache miss).
    constexpr std::size_t kPrefetchAhead = 8;
    constexpr auto kLanes = static_cast<std::size_t>(Bvh8Accel::kBlockLanes);
    parallel_for(listed, kRaysPerTask, threads, [&](std::size_t first, std::size_t last) {
        std::vector<float> task_times;
        std::vector<Bvh8Accel::Block> blocks;
        std::vector<double> block_far;  // the farthest depth of each of the cell's blocks
        std::size_t blocks_cell = std::numeric_limits<std::size_t>::max();
        dispatch_policies(impl_->test, false, [&]<class TriangleTestT, bool>() {
            // The ray prepared and broadcast once, its origin set for each: built per ray, its copies through
            // the stack stalled on store forwarding and its set-up's calls were not inlined (docs/python.md,
            // "Occupancy").
            PreparedRay<TriangleTestT> prepared(Ray{Vec3f(0.0f), direction, 0.0f, kInfinity});
            BlockRay<TriangleTestT, Bvh8Accel::kBlockLanes> block_ray(prepared, in_grid_order);
            for (std::size_t k = first; k < last; ++k) {
                if (k + kPrefetchAhead < listed) prefetch_line(&crossings[by_cell[k + kPrefetchAhead].index]);
                const RayInCell& ray = by_cell[k];
                const std::uint32_t cell = ray.cell, i = ray.index;
                const Vec3f origin = ray.origin();
                if (cell != blocks_cell) {
                    const std::span<const std::uint32_t> prims = grid->primitives(cell);
                    blocks.clear();
                    append_leaf_blocks(in_grid_order, prims, blocks);
                    block_far.clear();
                    for (std::size_t last_lane = kLanes - 1; last_lane < prims.size() + kLanes - 1;
                         last_lane += kLanes)
                        block_far.push_back(grid->far_depth(
                            in_grid_order.triangles[prims[std::min(last_lane, prims.size() - 1)]]));
                    append_leaf_blocks(in_grid_order, grid->every_ray(), blocks);
                    blocks_cell = cell;
                }
                prepared.set_origin(origin);
                block_ray.kernel.set_origin(origin);
                task_times.clear();
                // The cell's blocks wholly behind the origin skipped (their triangles by far depth).
                const double behind = grid->depth(origin) - grid->depth_slack();
                const auto first_block = static_cast<std::size_t>(
                    std::lower_bound(block_far.begin(), block_far.end(), behind) - block_far.begin());
                for (std::size_t b = first_block; b < blocks.size(); ++b) {
                    each_block_hit(in_grid_order, blocks[b], block_ray,
                                   [&](const Hit& hit) { task_times.push_back(hit.t); });
                }
                crossings[i] = distinct_count(task_times);
            }
        });
    });
    // Arrays for more rays than kKeptRays are dropped: kept, a call of 10^8 points would hold 4 GB after it.
    constexpr std::size_t kKeptRays = std::size_t{1} << 22;
    if (count > kKeptRays) buffers = CrossingBuffers{};
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
