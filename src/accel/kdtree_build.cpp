#include "accel/kdtree_build.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "accel/build_util.hpp"
#include "core/parallel.hpp"

namespace lancer {

int kdtree_depth_limit(const KdTreeOptions& options, std::size_t primitive_count) {
    if (options.max_depth < 0) throw std::invalid_argument("KdTreeOptions::max_depth must be >= 0");
    int limit = options.max_depth;
    if (limit == 0) {
        const double n = static_cast<double>(std::max<std::size_t>(primitive_count, 1));
        limit = 8 + static_cast<int>(1.3 * std::log2(n));
    }
    return std::min(limit, kKdTreeMaxDepth);
}

double kdtree_split_cost(const KdTreeOptions& options, double left_probability, double right_probability,
                         std::size_t left_count, std::size_t right_count) {
    const double weighted = left_probability * static_cast<double>(left_count) +
                            right_probability * static_cast<double>(right_count);
    if (options.cost == KdTreeCost::Seed003) return weighted;
    const double factor = left_count == 0 || right_count == 0 ? 1.0 - double{options.empty_bonus} : 1.0;
    return double{options.traversal_cost} + double{options.intersection_cost} * weighted * factor;
}

double kdtree_leaf_cost(const KdTreeOptions& options, std::size_t count) {
    const double n = static_cast<double>(count);
    return options.cost == KdTreeCost::Seed003 ? n : double{options.intersection_cost} * n;
}

namespace {

// Wald & Havran's events: one per primitive and axis where its clipped box lies in a plane,
// else one where it starts and one where it ends. At equal position the sweep must see ends, then planar
// events, then starts; the enum's order is that order.
enum class EventType : std::uint32_t { End = 0, Planar = 1, Start = 2 };

constexpr std::uint32_t kPrimitiveBits = 30;
constexpr std::uint32_t kPrimitiveMask = (std::uint32_t{1} << kPrimitiveBits) - 1;

// 8 bytes: position (4), type in the top 2 bits and primitive in the low 30 (4). Comparing the key compares
// (type, primitive): sorting on (position, key) gives the sweep order with ties broken by primitive index,
// so the order, and the tree, never depend on the sort's stability.
struct Event {
    float position;
    std::uint32_t key;

    Event(float p, EventType type, std::uint32_t prim)
        : position(p), key((static_cast<std::uint32_t>(type) << kPrimitiveBits) | prim) {}
    [[nodiscard]] EventType type() const { return static_cast<EventType>(key >> kPrimitiveBits); }
    [[nodiscard]] std::uint32_t prim() const { return key & kPrimitiveMask; }
    [[nodiscard]] bool operator<(const Event& o) const {
        return position < o.position || (position == o.position && key < o.key);
    }
};
static_assert(sizeof(Event) == 8);

using EventList = std::vector<Event>;
using AxisEvents = std::array<EventList, 3>;  // one sorted list per axis (the O(N log N) variant)

void add_events(AxisEvents& events, std::uint32_t prim, const Box3f& clipped) {
    for (int axis = 0; axis < 3; ++axis) {
        auto& list = events[static_cast<std::size_t>(axis)];
        if (clipped.lo[axis] == clipped.hi[axis]) {
            list.emplace_back(clipped.lo[axis], EventType::Planar, prim);
        } else {
            list.emplace_back(clipped.lo[axis], EventType::Start, prim);
            list.emplace_back(clipped.hi[axis], EventType::End, prim);
        }
    }
}

// The O(N log N) splice: merges the sorted events generated for the straddling primitives into the
// child's list, which the stable partition of the parent's list kept sorted.
void merge_new_events(EventList& list, EventList& added) {
    std::sort(added.begin(), added.end());
    const auto middle = static_cast<std::ptrdiff_t>(list.size());
    list.insert(list.end(), added.begin(), added.end());
    std::inplace_merge(list.begin(), list.begin() + middle, list.end());
}

enum class Side : std::uint8_t { Both, LeftOnly, RightOnly };

// Nodes with more primitives than this build their two children as subtrees of their own (in parallel with
// TBB) and splice them in, left then right: the serial layout. The rule depends on the data only, never on
// the thread count, and the subtrees' SAH sums are added in the same tree order, so 1 and N threads build
// the same tree, bit for bit.
constexpr std::size_t kParallelSubtree = 4096;

// Per primitive: the scratch of the left/right classification, valid for the node at hand only. One per
// thread: a task reads it only between its classification and its recursion, so a thread that picks up
// another task while it waits for its children finds the scratch free.
class SideScratch {
  public:
    explicit SideScratch(std::size_t primitive_count) : primitive_count_(primitive_count) {}

    [[nodiscard]] std::vector<Side>& local() {
        std::vector<Side>& sides = per_thread_.local();
        if (sides.size() != primitive_count_) sides.assign(primitive_count_, Side::Both);
        return sides;
    }

  private:
    std::size_t primitive_count_;
    parallel::PerThread<std::vector<Side>> per_thread_;
};

[[nodiscard]] double surface_area(const Box3f& box) {
    const double x = double{box.hi.x} - box.lo.x, y = double{box.hi.y} - box.lo.y,
                 z = double{box.hi.z} - box.lo.z;
    return 2.0 * (x * y + y * z + z * x);
}

class Builder {
  public:
    Builder(const Geometry& geometry, const KdTreeOptions& options, KdTreeData& tree, SideScratch& scratch)
        : geometry_(geometry), options_(options), tree_(tree), scratch_(scratch) {}

    void build() {
        std::vector<std::uint32_t> valid;
        for (std::uint32_t prim = 0; prim < geometry_.size(); ++prim) {
            const Box3f bounds = primitive_bounds(geometry_, prim);
            if (bounds.empty()) continue;
            tree_.bounds.extend(bounds);
            valid.push_back(prim);
        }
        tree_.depth_limit = kdtree_depth_limit(options_, valid.size());
        tree_.tolerance = geometric_tolerance(tree_.bounds);
        root_area_ = surface_area(tree_.bounds);
        if (valid.empty() || !(root_area_ > 0.0) || !std::isfinite(root_area_)) {
            // Nothing to split: no primitive, or a root box that is a point, a segment or unbounded.
            emit_leaf(std::move(valid), tree_.bounds, 0);
        } else {
            AxisEvents events;
            for (auto& list : events)
                list.reserve(2 * valid.size());
            for (std::uint32_t prim : valid)
                add_events(events, prim, primitive_bounds(geometry_, prim));
            parallel::invoke(
                [&] { sort_events(events[0]); },
                [&] { parallel::invoke([&] { sort_events(events[1]); }, [&] { sort_events(events[2]); }); });
            build_node(std::move(events), tree_.bounds, valid.size(), 0);
        }
        KdTreeBuildStats& stats = tree_.stats;
        stats.mean_depth = depth_sum_ / static_cast<double>(stats.leaves);
        const std::size_t filled = stats.leaves - stats.empty_leaves;
        stats.mean_refs_per_leaf =
            filled > 0 ? static_cast<double>(stats.references) / static_cast<double>(filled) : 0.0;
        stats.sah_cost = root_area_ > 0.0 && std::isfinite(root_area_)
                             ? cost_sum_ / root_area_
                             : double{options_.intersection_cost} * static_cast<double>(stats.references);
    }

  private:
    // Event is totally ordered (position, then type and primitive), so any sort gives the same list.
    static void sort_events(EventList& list) { parallel::sort(list.begin(), list.end()); }

    struct Split {
        int axis = -1;
        float position = 0.0f;
        bool planar_left = true;  // where the primitives lying in the plane go
        double cost = std::numeric_limits<double>::infinity();
    };

    // Wald & Havran's incremental sweep: with the events sorted, the counts left of, right of
    // and in each candidate plane follow from the events at smaller positions. Candidates are the clipped
    // boxes' bounds strictly inside the node: a plane on a face cuts nothing off, and would let the empty
    // bonus reward a zero-volume child forever (3000 coincident triangles).
    [[nodiscard]] Split find_split(const AxisEvents& events, const Box3f& box, std::size_t count) const {
        Split best;
        const double inverse_area = 1.0 / surface_area(box);
        for (int axis = 0; axis < 3; ++axis) {
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            const double extent_u = double{box.hi[u]} - box.lo[u], extent_v = double{box.hi[v]} - box.lo[v];
            auto child_area = [&](double extent) {
                return 2.0 * (extent * (extent_u + extent_v) + extent_u * extent_v);
            };
            const EventList& list = events[static_cast<std::size_t>(axis)];
            std::size_t left = 0, right = count;
            for (std::size_t i = 0; i < list.size();) {
                const float plane = list[i].position;
                std::size_t ending = 0, planar = 0, starting = 0;
                for (; i < list.size() && list[i].position == plane && list[i].type() == EventType::End; ++i)
                    ++ending;
                for (; i < list.size() && list[i].position == plane && list[i].type() == EventType::Planar;
                     ++i)
                    ++planar;
                for (; i < list.size() && list[i].position == plane && list[i].type() == EventType::Start;
                     ++i)
                    ++starting;
                right -= planar + ending;
                if (box.lo[axis] < plane && plane < box.hi[axis]) {
                    const double p_left = child_area(double{plane} - box.lo[axis]) * inverse_area;
                    const double p_right = child_area(double{box.hi[axis]} - plane) * inverse_area;
                    // Wald & Havran: the planar primitives go to the side where they cost less.
                    const double cost_left =
                        kdtree_split_cost(options_, p_left, p_right, left + planar, right);
                    const double cost_right =
                        kdtree_split_cost(options_, p_left, p_right, left, right + planar);
                    const double cost = std::min(cost_left, cost_right);
                    if (cost < best.cost) best = {axis, plane, cost_left <= cost_right, cost};
                }
                left += starting + planar;
            }
        }
        return best;
    }

    void build_node(AxisEvents events, const Box3f& box, std::size_t count, int depth) {
        const Split split = depth < tree_.depth_limit && count > 0 ? find_split(events, box, count) : Split{};
        // Wald & Havran's termination: stop when no split is cheaper than the leaf.
        if (split.axis < 0 || !(split.cost < kdtree_leaf_cost(options_, count))) {
            std::vector<std::uint32_t> prims;
            prims.reserve(count);
            for (const Event& event : events[0]) {
                if (event.type() != EventType::End) prims.push_back(event.prim());
            }
            std::sort(prims.begin(), prims.end());
            emit_leaf(std::move(prims), box, depth);
            return;
        }
        const std::uint32_t index = reserve_node();
        cost_sum_ += double{options_.traversal_cost} * surface_area(box);

        const int axis = split.axis;
        const float plane = split.position;
        Box3f left_box = box, right_box = box;
        left_box.hi[axis] = plane;
        right_box.lo[axis] = plane;

        // Wald & Havran's "ClassifyLeftRightBoth": a primitive whose clipped box ends at or before the
        // plane is left only, one that starts at or after it right only, a planar one follows its position
        // or, in the plane, the side the cost chose; the rest straddle.
        std::vector<Side>& sides = scratch_.local();
        const EventList& split_list = events[static_cast<std::size_t>(axis)];
        for (const Event& event : split_list)
            sides[event.prim()] = Side::Both;
        for (const Event& event : split_list) {
            Side& side = sides[event.prim()];
            switch (event.type()) {
                case EventType::End:
                    if (event.position <= plane) side = Side::LeftOnly;
                    break;
                case EventType::Start:
                    if (event.position >= plane) side = Side::RightOnly;
                    break;
                case EventType::Planar:
                    side = event.position < plane || (event.position == plane && split.planar_left)
                               ? Side::LeftOnly
                               : Side::RightOnly;
                    break;
            }
        }

        // Perfect splits (section 4.2): each straddling primitive is clipped again to each child's box,
        // which gives its new events there; it is dropped from a child it does not reach.
        AxisEvents left_events, right_events, new_left, new_right;
        std::size_t left_count = 0, right_count = 0;
        for (const Event& event : split_list) {
            if (event.type() == EventType::End) continue;  // one event per primitive: its start or planar one
            const std::uint32_t prim = event.prim();
            if (sides[prim] == Side::LeftOnly) {
                ++left_count;
            } else if (sides[prim] == Side::RightOnly) {
                ++right_count;
            } else {
                const Box3f left_part = part_in(prim, left_box);
                const Box3f right_part = part_in(prim, right_box);
                if (!left_part.empty()) add_events(new_left, prim, left_part), ++left_count;
                if (!right_part.empty()) add_events(new_right, prim, right_part), ++right_count;
            }
        }
        // The splice proper: one linear pass per axis keeps the one-sided events in order.
        for (std::size_t a = 0; a < 3; ++a) {
            for (const Event& event : events[a]) {
                const Side side = sides[event.prim()];
                if (side == Side::LeftOnly) {
                    left_events[a].push_back(event);
                } else if (side == Side::RightOnly) {
                    right_events[a].push_back(event);
                }
            }
            EventList().swap(
                events[a]);  // the parent's lists are no longer needed: free them before recursing
            merge_new_events(left_events[a], new_left[a]);
            merge_new_events(right_events[a], new_right[a]);
            EventList().swap(new_left[a]);
            EventList().swap(new_right[a]);
        }

        if (count <= kParallelSubtree) {
            build_node(std::move(left_events), left_box, left_count, depth + 1);
            const auto above = static_cast<std::uint32_t>(tree_.nodes.size());
            build_node(std::move(right_events), right_box, right_count, depth + 1);
            tree_.nodes[index] = KdNode::inner(axis, plane, above);
            return;
        }
        KdTreeData left_tree, right_tree;
        left_tree.depth_limit = right_tree.depth_limit = tree_.depth_limit;
        Builder left(geometry_, options_, left_tree, scratch_),
            right(geometry_, options_, right_tree, scratch_);
        parallel::invoke(
            [&] { left.build_node(std::move(left_events), left_box, left_count, depth + 1); },
            [&] { right.build_node(std::move(right_events), right_box, right_count, depth + 1); });
        splice(left);
        const auto above = static_cast<std::uint32_t>(tree_.nodes.size());
        splice(right);
        tree_.nodes[index] = KdNode::inner(axis, plane, above);
    }

    // Appends a subtree built by another Builder (its node and reference indices start at 0) and its sums.
    void splice(const Builder& subtree) {
        const KdTreeData& sub = subtree.tree_;
        if (tree_.nodes.size() + sub.nodes.size() > KdNode::kMaxField)
            throw std::length_error("kd-tree: too many nodes");
        if (tree_.references.size() + sub.references.size() > std::numeric_limits<std::uint32_t>::max())
            throw std::length_error("kd-tree: too many references");
        const auto node_base = static_cast<std::uint32_t>(tree_.nodes.size());
        const auto reference_base = static_cast<std::uint32_t>(tree_.references.size());
        for (const KdNode& node : sub.nodes) {
            if (!node.is_leaf()) {
                tree_.nodes.push_back(
                    KdNode::inner(node.axis(), node.split(), node.above_child() + node_base));
            } else {
                // One primitive is stored inline; otherwise the payload is an offset into the references.
                const std::uint32_t count = node.primitive_count();
                tree_.nodes.push_back(
                    count == 1 ? node : KdNode::leaf(count, node.reference_offset() + reference_base));
            }
        }
        tree_.references.insert(tree_.references.end(), sub.references.begin(), sub.references.end());
        KdTreeBuildStats& stats = tree_.stats;
        stats.leaves += sub.stats.leaves;
        stats.empty_leaves += sub.stats.empty_leaves;
        stats.references += sub.stats.references;
        stats.max_refs_per_leaf = std::max(stats.max_refs_per_leaf, sub.stats.max_refs_per_leaf);
        stats.max_depth = std::max(stats.max_depth, sub.stats.max_depth);
        depth_sum_ += subtree.depth_sum_;
        cost_sum_ += subtree.cost_sum_;
    }

    // Bounds of the part of the primitive in the box, empty when it misses the box. A sphere's clipped bounds
    // are its bounds cut to the box, so the sphere-box distance test drops the boxes only its corners reach.
    [[nodiscard]] Box3f part_in(std::uint32_t prim, const Box3f& box) const {
        if (prim >= geometry_.triangles.size() && !primitive_overlaps_box(geometry_, prim, box)) return {};
        return clipped_primitive_bounds(geometry_, prim, box);
    }

    std::uint32_t reserve_node() {
        if (tree_.nodes.size() > KdNode::kMaxField) throw std::length_error("kd-tree: too many nodes");
        tree_.nodes.push_back(KdNode::leaf(0, 0));
        return static_cast<std::uint32_t>(tree_.nodes.size() - 1);
    }

    void emit_leaf(std::vector<std::uint32_t> prims, const Box3f& box, int depth) {
        reserve_node();
        const std::size_t count = prims.size();
        if (count > KdNode::kMaxField) throw std::length_error("kd-tree: too many primitives in a leaf");
        const std::uint32_t payload =
            count == 1 ? prims[0] : static_cast<std::uint32_t>(tree_.references.size());
        if (count > 1) {
            if (tree_.references.size() + count > std::numeric_limits<std::uint32_t>::max())
                throw std::length_error("kd-tree: too many references");
            tree_.references.insert(tree_.references.end(), prims.begin(), prims.end());
        }
        tree_.nodes.back() = KdNode::leaf(static_cast<std::uint32_t>(count), payload);

        KdTreeBuildStats& stats = tree_.stats;
        ++stats.leaves;
        stats.empty_leaves += count == 0 ? 1 : 0;
        stats.references += count;
        stats.max_refs_per_leaf = std::max(stats.max_refs_per_leaf, count);
        stats.max_depth = std::max(stats.max_depth, depth);
        depth_sum_ += depth;
        cost_sum_ += double{options_.intersection_cost} * static_cast<double>(count) * surface_area(box);
    }

    const Geometry& geometry_;
    const KdTreeOptions& options_;
    KdTreeData& tree_;
    SideScratch& scratch_;
    double root_area_ = 0.0;
    double depth_sum_ = 0.0;
    double cost_sum_ = 0.0;  // sum of Ct SA(inner) + Ci N SA(leaf), divided by SA(root) at the end
};

}  // namespace

KdTreeData build_kdtree(const Geometry& geometry, const KdTreeOptions& options) {
    if (geometry.size() > kPrimitiveMask) throw std::length_error("kd-tree: more than 2^30 - 1 primitives");
    KdTreeData tree;
    SideScratch scratch(geometry.size());
    Builder(geometry, options, tree, scratch).build();
    return tree;
}

}  // namespace lancer
