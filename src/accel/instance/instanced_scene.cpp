// The two-level scene: objects built once, instances placing them, a binary SAH BVH over the instances' world
// boxes whose walk moves the ray into each instance's frame and traces the object's structure with the
// closest hit so far as tfar. docs/accel/instances.md has the design note.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>

#include "accel/build_util.hpp"
#include "accel/bvh/build.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "accel/bvh/collapse.hpp"
#include "accel/bvh/refit.hpp"
#include "accel/instance/affine.hpp"
#include "accel/instance/bounding_polytope.hpp"
#include "accel/instance/top_level_walk.hpp"
#include "accel/tree_shape.hpp"
#include "core/intersect.hpp"
#include "core/parallel.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/instances.hpp"

namespace lancer {

namespace {

using top_level::InstanceRecord, top_level::ObjectRecord, top_level::kTopWidth, top_level::TopNode;

// An instance's box grows, beyond its object's box mapped to the world, by the transformed ray's rounding
// seen from the world: the object ray errs by 2^-24 of its coordinates, |o'| + t |d'| <= ||A^-1|| (|o - b|
// + t |d|), so the hit by condition x 2^-24 (|o - b| + t |d|) in the world. Ray conditioning keeps origins
// within 4 sides of the scene's centre and hits within 4.5, whence |o - b| + t |d| <= 9 sides + |c - b|;
// the factor 2^-22 leaves 4 times that (docs/numerical-contract.md, "Instances").
constexpr double kTransformedRayRounding = 0x1p-22;
constexpr double kRayReachSides = 9.0;

// Rays per task of intersect_parallel and occluded_parallel, as for the structures (lancer/accel.hpp).
constexpr std::size_t kRayChunk = 4096;

// The box of `points` under `transform`: mapped in double, rounded outwards. The points and the transform
// (place() refuses a NaN or infinite entry first) are finite, so std::min and std::max serve: they inline,
// where std::fmin and std::fmax are calls into libm, and every instance update maps each point.
Box3f world_box(std::span<const Vec3d> points, const Transform& transform) {
    double lo[3] = {kInfinity, kInfinity, kInfinity}, hi[3] = {-kInfinity, -kInfinity, -kInfinity};
    for (const Vec3d& p : points) {
        for (int r = 0; r < 3; ++r) {
            const double mapped = double(transform.m[r][0]) * p.x + double(transform.m[r][1]) * p.y +
                                  double(transform.m[r][2]) * p.z + double(transform.m[r][3]);
            lo[r] = std::min(lo[r], mapped), hi[r] = std::max(hi[r], mapped);
        }
    }
    return {{round_down(lo[0]), round_down(lo[1]), round_down(lo[2])},
            {round_up(hi[0]), round_up(hi[1]), round_up(hi[2])}};
}

std::array<Vec3d, 8> corners(const Box3f& box) {
    auto corner = [&](int bits) {
        return Vec3d(bits & 1 ? box.hi.x : box.lo.x, bits & 2 ? box.hi.y : box.lo.y,
                     bits & 4 ? box.hi.z : box.lo.z);
    };
    return {corner(0), corner(1), corner(2), corner(3), corner(4), corner(5), corner(6), corner(7)};
}

double elapsed_ms(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

struct InstancedScene::State {
    BuildOptions top_level;
    std::vector<ObjectRecord> objects;
    // By instance id; a removed instance keeps its slot (ids are never given again).
    std::vector<InstanceRecord> records;
    std::vector<Transform> transforms;
    std::vector<std::uint8_t> alive;
    // The object's hull points mapped to the world, before the rounding margin.
    std::vector<Box3f> object_boxes;
    // What the top level holds: object_boxes grown by the ray's rounding.
    std::vector<Box3f> leaf_boxes;
    std::size_t live = 0;
    std::size_t instanced_primitives = 0;

    // The top level: 8-wide nodes collapsed from build_bvh_over_boxes's binary tree over the live ids; a leaf
    // slot holds one instance (child: its id, prim_count 1).
    std::vector<TopNode> nodes;
    Box3f bounds;
    double built_sah_cost = 0.0, sah_ratio = 1.0, build_ms = 0.0;
    bool added_or_removed = false, moved = false;

    [[nodiscard]] const BvhOptions& bvh_options() const { return top_level.group<BvhOptions>(); }

    // The id the next instance gets, or std::invalid_argument once a hit's id could not hold it.
    [[nodiscard]] std::uint32_t next_id() const {
        if (records.size() >= std::size_t(std::numeric_limits<std::int32_t>::max()))
            throw std::invalid_argument("InstancedScene: more instances than a hit's 32-bit id numbers");
        return static_cast<std::uint32_t>(records.size());
    }

    void check_instance(std::uint32_t instance, const char* what) const {
        if (instance >= alive.size() || alive[instance] == 0) {
            throw std::invalid_argument(std::string("InstancedScene::") + what + ": no instance " +
                                        std::to_string(instance) + " (never added, or removed)");
        }
    }

    // The record and world box of `instance` placed by `transform`, checked; throws naming the instance.
    std::pair<InstanceRecord, Box3f> place(std::uint32_t instance, std::uint32_t object,
                                           const Transform& transform) const {
        std::string problem;
        const FarOriginFrame frame(objects[object].traced->bounds());
        const Box3f& object_bounds = objects[object].traced->bounds();
        const Box3f grown = object_bounds.grown(geometric_tolerance(object_bounds));
        InstanceRecord record{
            invert(transform, problem), objects[object].traced,     object, frame.centre(), frame.far_limit(),
            objects[object].walk,       top_level::ObjectBox(grown)};
        if (!problem.empty()) {
            throw std::invalid_argument("InstancedScene: instance " + std::to_string(instance) +
                                        "'s transform " + problem);
        }
        // The box of the object's hull points: within the box of its grown box's corners (up to the
        // polytope's slack), the polytope's axis slabs being that box's faces.
        const Box3f box = world_box(objects[object].hull_points, transform);
        if (!in_coordinate_domain(box.lo) || !in_coordinate_domain(box.hi)) {
            throw std::invalid_argument("InstancedScene: instance " + std::to_string(instance) +
                                        "'s transform takes its object outside the coordinate domain [-2^60, "
                                        "2^60]");
        }
        return {record, box};
    }

    // The leaves' boxes and the scene's box from the instances' mapped hull points (object_boxes).
    void grow_leaf_boxes() {
        bounds = parallel::reduce(
            0, alive.size(), 16384, Box3f{},
            [&](std::size_t from, std::size_t to, Box3f box) {
                for (std::size_t id = from; id < to; ++id) {
                    if (alive[id] != 0) box.extend(object_boxes[id]);
                }
                return box;
            },
            [](Box3f a, const Box3f& b) {
                a.extend(b);
                return a;
            });
        if (bounds.empty()) return;
        const double side = max_component(bounds.extent());
        const Vec3f centre = bounds.center();
        parallel::for_each_chunk(0, alive.size(), 16384, [&](std::size_t from, std::size_t to) {
            for (std::size_t id = from; id < to; ++id) {
                if (alive[id] == 0) continue;
                const Transform& transform = transforms[id];
                const double offset = std::fmax(std::fabs(centre.x - double(transform.m[0][3])),
                                                std::fmax(std::fabs(centre.y - double(transform.m[1][3])),
                                                          std::fabs(centre.z - double(transform.m[2][3]))));
                const double margin = records[id].to_object.condition * kTransformedRayRounding *
                                      (kRayReachSides * side + offset);
                leaf_boxes[id] = object_boxes[id].grown(round_up(margin));
            }
        });
    }

    void rebuild() {
        std::vector<std::uint32_t> ids;
        ids.reserve(live);
        for (std::uint32_t id = 0; id < alive.size(); ++id) {
            if (alive[id] != 0) ids.push_back(id);
        }
        // One instance a leaf, whatever bvh.max_leaf_size says: visiting an instance maps the ray and walks
        // its object from the root, which costs far more than the SAH's unit primitive cost, so each
        // instance's own box is tested first (a leaf of 4 traced instances its box had no reason to).
        BvhOptions options = bvh_options();
        options.max_leaf_size = 1;
        const BvhBuildResult built = build_bvh_over_boxes(leaf_boxes, ids, options);
        nodes.clear();
        if (!built.nodes.empty()) static_cast<void>(collapse(built, 0));
        built_sah_cost = wide_bvh_sah_cost<top_level::kTopWidth>(nodes);
        sah_ratio = 1.0;
    }

    // The binary subtree under `binary_root` as wide nodes appended depth first; returns the first's index.
    // Each node's children by the wide BVHs' greedy collapse (collapse_children, accel/bvh/collapse.hpp).
    std::uint32_t collapse(const BvhBuildResult& binary, std::uint32_t binary_root) {
        std::array<std::uint32_t, kTopWidth> children{};
        const int count = collapse_children<kTopWidth>(
            binary.nodes, binary_root, [&](std::uint32_t i) { return binary.nodes[i].is_leaf(); }, children);
        const auto index = static_cast<std::uint32_t>(nodes.size());
        nodes.emplace_back();
        for (int slot = 0; slot < count; ++slot) {
            const BvhNode& child = binary.nodes[children[slot]];
            for (int axis = 0; axis < 3; ++axis) {
                nodes[index].bounds[TopNode::kLo][axis][slot] = child.lo[axis];
                nodes[index].bounds[TopNode::kHi][axis][slot] = child.hi[axis];
            }
            if (child.is_leaf()) {
                nodes[index].child[slot] = binary.prim_indices[child.offset];
                nodes[index].prim_count[slot] = 1;
            } else {
                // Not a reference into `nodes`: the recursion may reallocate it.
                const std::uint32_t child_index = collapse(binary, children[slot]);
                nodes[index].child[slot] = child_index;
            }
        }
        return index;
    }

    // The wide nodes' boxes from the leaves' boxes, bottom-up, each grown by the tolerance of their union as
    // the build grows them (NodeSlots::compact), so that a refit to the boxes the tree was built on gives its
    // nodes back bit for bit. Returns the box of node `index`'s children.
    Box3f refit(std::uint32_t index, float margin) {
        Box3f node_box;
        for (int slot = 0; slot < kTopWidth; ++slot) {
            TopNode& node = nodes[index];
            if (node.is_empty(slot)) continue;
            const Box3f box = node.prim_count[slot] > 0 ? leaf_boxes[node.child[slot]].grown(margin)
                                                        : refit(node.child[slot], margin);
            TopNode& refitted = nodes[index];  // the recursion does not reallocate, but reads it again
            for (int axis = 0; axis < 3; ++axis) {
                refitted.bounds[TopNode::kLo][axis][slot] = box.lo[axis];
                refitted.bounds[TopNode::kHi][axis][slot] = box.hi[axis];
            }
            node_box.extend(box);
        }
        return node_box;
    }

    // Refits the whole top level; returns its SAH cost.
    double refit_top_level() {
        if (nodes.empty()) return 0.0;
        Box3f leaves;
        for (std::size_t id = 0; id < alive.size(); ++id) {
            if (alive[id] != 0) leaves.extend(leaf_boxes[id]);
        }
        static_cast<void>(refit(0, geometric_tolerance(leaves)));
        return wide_bvh_sah_cost<top_level::kTopWidth>(nodes);
    }

    void check_committed(std::size_t ray_count, std::size_t answer_count) const {
        if (added_or_removed || moved) {
            throw std::logic_error(
                "InstancedScene: instances changed since the last commit(); commit before tracing");
        }
        if (ray_count != answer_count)
            throw std::invalid_argument("InstancedScene: one answer slot per ray expected");
    }

    // A packet of rays walks the top level together when their origins lie within this share of the
    // scene's largest side (InstancedScene::Walk::load): a camera tile's rays share theirs.
    static constexpr float kCoherentShare = 1.0f / 256.0f;

    template <bool kAnyHit, class Answer>
    void walk_each(std::span<const Ray> traced, std::span<Answer> answers,
                   TraversalCounters* counters) const {
        Walk(nodes, records, bounds, max_component(bounds.extent()) * kCoherentShare)
            .each<kAnyHit>(traced, answers, counters);
    }
};

InstancedScene::InstancedScene(const BuildOptions& top_level) : state_(std::make_unique<State>()) {
    state_->top_level = top_level;
}
InstancedScene::~InstancedScene() = default;
InstancedScene::InstancedScene(InstancedScene&&) noexcept = default;
InstancedScene& InstancedScene::operator=(InstancedScene&&) noexcept = default;

std::uint32_t InstancedScene::add_object(std::shared_ptr<const Accel> structure) {
    if (structure == nullptr) throw std::invalid_argument("InstancedScene::add_object: null structure");
    if (structure->bounds().empty()) {
        throw std::invalid_argument("InstancedScene::add_object: structure '" +
                                    std::string(structure->name()) +
                                    "' is unbuilt or has nothing that can be hit");
    }
    ObjectRecord object;
    // A packet structure is traced through the single-ray structure it holds, which holds the geometry at the
    // packet structure's scale (Accel::built_geometry) and sees it at scale 1: for a scene outside the
    // ordinary size range, the packet structure itself, which scales the rays, is the one traced.
    const Accel* single_ray = structure->exported_layout().single_ray;
    object.traced = single_ray != nullptr && structure->scale_exponent() == 0 ? single_ray : structure.get();
    object.walk = object.traced->single_ray_walk();
    object.primitives = structure->stats().primitives;
    const Box3f& object_bounds = object.traced->bounds();
    const float tolerance = geometric_tolerance(object_bounds);
    object.hull_points = top_level::bounding_polytope(structure->built_geometry(),
                                                      structure->scale_exponent(), object_bounds, tolerance);
    if (object.hull_points.empty()) {
        const std::array<Vec3d, 8> box_corners = corners(object_bounds.grown(tolerance));
        object.hull_points.assign(box_corners.begin(), box_corners.end());
    }
    object.structure = std::move(structure);
    state_->objects.push_back(std::move(object));
    return static_cast<std::uint32_t>(state_->objects.size() - 1);
}

std::uint32_t InstancedScene::add_object(const TriangleMesh& mesh, std::string_view accel_name,
                                         const BuildOptions& options) {
    auto triangles = std::make_shared<std::vector<Triangle>>(mesh.triangles());
    std::shared_ptr<Accel> structure = make_accel(accel_name);
    structure->build(Geometry{*triangles, {}}, options);
    const std::uint32_t id = add_object(std::move(structure));
    state_->objects.back().triangles = std::move(triangles);
    return id;
}

std::size_t InstancedScene::object_count() const {
    return state_->objects.size();
}

const Accel& InstancedScene::object(std::uint32_t object) const {
    if (object >= state_->objects.size()) {
        throw std::invalid_argument("InstancedScene::object: no object " + std::to_string(object));
    }
    return *state_->objects[object].structure;
}

std::uint32_t InstancedScene::add_instance(std::uint32_t object, const Transform& object_to_world) {
    State& s = *state_;
    const std::uint32_t id = s.next_id();
    if (object >= s.objects.size()) {
        throw std::invalid_argument("InstancedScene: instance " + std::to_string(id) + " names object " +
                                    std::to_string(object) + ", but the scene has " +
                                    std::to_string(s.objects.size()));
    }
    const auto [record, box] = s.place(id, object, object_to_world);
    s.records.push_back(record);
    s.transforms.push_back(object_to_world);
    s.alive.push_back(1);
    s.object_boxes.push_back(box);
    s.leaf_boxes.push_back(box);
    ++s.live;
    s.instanced_primitives += s.objects[object].primitives;
    s.added_or_removed = true;
    return id;
}

std::uint32_t InstancedScene::skip_instance_id() {
    State& s = *state_;
    const std::uint32_t id = s.next_id();
    // A removed instance's slot: never in the top level, never counted.
    s.records.emplace_back();
    s.transforms.emplace_back();
    s.alive.push_back(0);
    s.object_boxes.emplace_back();
    s.leaf_boxes.emplace_back();
    return id;
}

void InstancedScene::set_transform(std::uint32_t instance, const Transform& object_to_world) {
    State& s = *state_;
    s.check_instance(instance, "set_transform");
    const auto [record, box] = s.place(instance, s.records[instance].object, object_to_world);
    s.records[instance] = record;
    s.transforms[instance] = object_to_world;
    s.object_boxes[instance] = box;
    s.moved = true;
}

void InstancedScene::remove_instance(std::uint32_t instance) {
    State& s = *state_;
    s.check_instance(instance, "remove_instance");
    s.alive[instance] = 0;
    --s.live;
    s.instanced_primitives -= s.objects[s.records[instance].object].primitives;
    s.added_or_removed = true;
}

bool InstancedScene::contains(std::uint32_t instance) const {
    return instance < state_->alive.size() && state_->alive[instance] != 0;
}

const Transform& InstancedScene::transform(std::uint32_t instance) const {
    state_->check_instance(instance, "transform");
    return state_->transforms[instance];
}

std::uint32_t InstancedScene::object_of(std::uint32_t instance) const {
    state_->check_instance(instance, "object_of");
    return state_->records[instance].object;
}

std::size_t InstancedScene::instance_count() const {
    return state_->live;
}

std::size_t InstancedScene::instanced_primitive_count() const {
    return state_->instanced_primitives;
}

UpdateReport InstancedScene::commit() {
    State& s = *state_;
    const auto start = std::chrono::steady_clock::now();
    UpdateReport report{.method = UpdateMethod::Refit, .sah_ratio = s.sah_ratio};
    if (s.added_or_removed || s.moved) {
        s.grow_leaf_boxes();
        bool rebuild = s.added_or_removed;
        if (!rebuild) {
            s.sah_ratio = refit_sah_ratio(s.refit_top_level(), s.built_sah_cost);
            rebuild = s.sah_ratio > s.bvh_options().refit_threshold;
        }
        if (rebuild) {
            s.rebuild();
            s.build_ms = elapsed_ms(start);
        }
        report.method = rebuild ? UpdateMethod::Rebuild : UpdateMethod::Refit;
        report.sah_ratio = s.sah_ratio;
    }
    s.added_or_removed = s.moved = false;
    report.ms = report.structure_ms = elapsed_ms(start);
    return report;
}

void InstancedScene::intersect(std::span<const Ray> rays, std::span<InstanceHit> hits,
                               TraversalCounters* counters) const {
    const State& s = *state_;
    s.check_committed(rays.size(), hits.size());
    const ConditionedRays conditioned = condition_rays(rays, s.bounds);
    const std::span<const Ray> traced =
        conditioned.rays.empty() ? rays : std::span<const Ray>(conditioned.rays);
    s.walk_each<false>(traced, hits, counters);
    restore_hits(conditioned, rays, hits);
}

void InstancedScene::occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                              TraversalCounters* counters) const {
    const State& s = *state_;
    s.check_committed(rays.size(), occluded.size());
    const ConditionedRays conditioned = condition_rays(rays, s.bounds);
    const std::span<const Ray> traced =
        conditioned.rays.empty() ? rays : std::span<const Ray>(conditioned.rays);
    s.walk_each<true>(traced, occluded, counters);
}

const Box3f& InstancedScene::bounds() const {
    return state_->bounds;
}

AccelStats InstancedScene::stats() const {
    const State& s = *state_;
    AccelStats stats;
    stats.build_ms = s.build_ms;
    stats.primitives = s.instanced_primitives;
    stats.figures.push_back(count_figure("objects", s.objects.size(), "objects: structures built once"));
    stats.figures.push_back(count_figure("instances", s.live, "live instances, each an object placed"));
    stats.figures.push_back(
        count_figure("top_level_nodes", s.nodes.size(), "8-wide nodes of the top-level BVH"));
    stats.figures.push_back(value_figure("sah_cost", s.built_sah_cost * s.sah_ratio,
                                         "the top level's SAH cost, unit node and instance costs"));
    stats.figures.push_back(
        value_figure("sah_ratio", s.sah_ratio, "the top level's SAH cost over its cost as last built"));
    stats.memory_by_array = {
        {"top_level_nodes", s.nodes.size() * sizeof(TopNode)},
        {"instance_records", s.records.size() * sizeof(InstanceRecord)},
        {"transforms", s.transforms.size() * sizeof(Transform)},
        {"instance_boxes", (s.object_boxes.size() + s.leaf_boxes.size()) * sizeof(Box3f) + s.alive.size()},
    };
    return stats;
}

std::size_t InstancedScene::memory_bytes() const {
    std::size_t bytes = 0;
    for (const auto& [name, size] : stats().memory_by_array)
        bytes += size;
    return bytes;
}

void intersect_parallel(const InstancedScene& scene, std::span<const Ray> rays, std::span<InstanceHit> hits,
                        int threads) {
    if (rays.size() != hits.size())
        throw std::invalid_argument("InstancedScene: one answer slot per ray expected");
    parallel::with_threads(threads, [&] {
        parallel::for_each_block(rays.size(), kRayChunk, [&](std::size_t from, std::size_t to) {
            scene.intersect(rays.subspan(from, to - from), hits.subspan(from, to - from));
        });
    });
}

void occluded_parallel(const InstancedScene& scene, std::span<const Ray> rays,
                       std::span<std::uint8_t> occluded, int threads) {
    if (rays.size() != occluded.size()) {
        throw std::invalid_argument("InstancedScene: one answer slot per ray expected");
    }
    parallel::with_threads(threads, [&] {
        parallel::for_each_block(rays.size(), kRayChunk, [&](std::size_t from, std::size_t to) {
            scene.occluded(rays.subspan(from, to - from), occluded.subspan(from, to - from));
        });
    });
}

}  // namespace lancer
