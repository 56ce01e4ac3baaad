// The walk of seed 000 section 4 over the arrays of layout.hpp: entry by the boundary cube map (4.1), exit
// face by three Pluecker signs and a table (4.2.1), sub-face by two more signs and a table (4.2.2), the loop
// of 4.2.3. Phases in the code: ENTRY, LEAF, EXIT-FACE, NEIGHBOR. It deviates from the seed where an exact
// closest hit needs it: it goes on past the first leaf with a hit, descends the tree for rays that start
// inside, gives zero direction components a sign, and computes the Pluecker products in double
// (docs/plucker-octree.md, "The walk", "Zero direction components", "The Plücker products").
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "accel/plucker/conventions.hpp"
#include "accel/plucker/layout.hpp"
#include "core/intersect.hpp"
#include "core/vec3d.hpp"

namespace lancer::plucker {

// The ray as the walk sees it.
struct WalkRay {
    Vec3f origin;
    // The direction in double, for the Pluecker products d x w with w = P - o (exit_face, sub_face): each
    // product of two floats is exact in double, and one subtraction keeps the exact sign, so every sign is
    // that of the exact product for the computed w, whatever the magnitudes (no overflow at 2^128, no
    // underflow at 2^-149).
    Vec3d direction{0.0, 0.0, 0.0};
    Vec3f abs_direction;                // |d|, for the exit distance
    std::array<std::uint32_t, 3> up{};  // 1 when the ray leaves cells through their upper face on that axis
    std::array<std::uint8_t, 3> tie{};  // kQuadrantTieBits of the exit face on each axis
    int octant = 0;                     // the exit vertex, up[0] | up[1] << 1 | up[2] << 2

    WalkRay() = default;
    WalkRay(const Ray& ray, const OctreeCube& cube) : origin(ray.origin), direction(ray.direction) {
        for (int axis = 0; axis < 3; ++axis) {
            const float d = ray.direction[axis];
            abs_direction[axis] = std::fabs(d);
            const bool moves = d != 0.0f;
            const float centre = cube.lo[axis] + 0.5f * cube.size;
            up[static_cast<std::size_t>(axis)] = (moves ? d > 0.0f : ray.origin[axis] < centre) ? 1u : 0u;
            octant |= static_cast<int>(up[static_cast<std::size_t>(axis)]) << axis;
        }
        for (int axis = 0; axis < 3; ++axis) {
            const int face = make_face(axis, static_cast<int>(up[static_cast<std::size_t>(axis)]));
            tie[static_cast<std::size_t>(axis)] =
                kQuadrantTieBits[static_cast<std::size_t>(face)][static_cast<std::size_t>(octant)];
        }
    }
};

// Where a cell's planes come from: the boxes array (the seed's layout) or its integer coordinates and level
// (section 6: no stored boxes). `words` points at the cell's box word(s).
struct StoredBoxes {
    const PluckerBox* boxes;
    static constexpr bool kStored = true;

    struct Cell {
        const PluckerBox* box;
    };
    [[nodiscard]] Cell read(const std::uint32_t* words) const { return {boxes + words[0]}; }
    [[nodiscard]] static float exit_plane(const Cell& cell, int axis, std::uint32_t up) {
        return cell.box->planes[static_cast<std::size_t>(axis) + 6 * up];
    }
    [[nodiscard]] static float mid(const Cell& cell, int axis) { return cell.box->mid(axis); }
};

struct ComputedBoxes {
    OctreeCube cube;
    float tolerance;
    static constexpr bool kStored = false;

    struct Cell {
        std::array<std::uint32_t, 3> coordinates;
        int level;
    };
    [[nodiscard]] static Cell read(const std::uint32_t* words) {
        return {{words[0] & 0xFFFFu, words[0] >> 16, words[1] & 0xFFFFu}, static_cast<int>(words[1] >> 16)};
    }
    [[nodiscard]] float exit_plane(const Cell& cell, int axis, std::uint32_t up) const {
        return exit_plane_of(cube, tolerance, axis, cell.level,
                             cell.coordinates[static_cast<std::size_t>(axis)] + up);
    }
    [[nodiscard]] float mid(const Cell& cell, int axis) const {
        return cube.plane(axis, cell.level + 1, 2u * cell.coordinates[static_cast<std::size_t>(axis)] + 1u);
    }
};

// The leaf holding point p, from tree cell `node` of the given level and coordinates (the root, or a cube
// map texel's cell), with the same tie rule.
[[nodiscard]] inline std::uint32_t descend(const PluckerLayout& layout, std::uint32_t node, int level,
                                           std::array<std::uint32_t, 3> coordinates, const Vec3f& p,
                                           const WalkRay& ray) {
    while (layout.locate[node] & 1u) {
        std::uint32_t child = 0;
        for (int axis = 0; axis < 3; ++axis) {
            auto& c = coordinates[static_cast<std::size_t>(axis)];
            const float mid = layout.cube.plane(axis, level + 1, 2u * c + 1u);
            const std::uint32_t bit = ray.up[static_cast<std::size_t>(axis)] ? p[axis] >= mid : p[axis] > mid;
            child |= bit << axis;
            c = 2u * c + bit;
        }
        node = (layout.locate[node] >> 1) + child;
        ++level;
    }
    return layout.locate[node] >> 1;
}

// The interval of one slab [lo, hi] along a ray, the exit widened by its rounding. NaN (the origin on a
// plane, no motion along the axis): the ray runs inside the closed slab.
struct SlabInterval {
    float near_t, far_t;
};
[[nodiscard]] inline SlabInterval slab_interval(float lo, float hi, float origin, float inverse) {
    const float t_lo = (lo - origin) * inverse, t_hi = (hi - origin) * inverse;
    if (std::isnan(t_lo) || std::isnan(t_hi)) return {-kInfinity, kInfinity};
    return {std::min(t_lo, t_hi), widened_slab_exit(std::max(t_lo, t_hi))};
}

// ENTRY (seed 000 section 4.1): the first leaf along [tnear, tfar], or false when the ray misses the
// geometry's bounds (grown by the scene's tolerance, as every structure's boxes: docs/numerical-contract.md).
// The seed enters by the root's faces; the root is a cube anchored at the bounds' lower corner, and the walk
// starts and ends at the bounds instead, so that it does not cross the root's empty rest (PluckerLayout::
// bounds). walk_end: where the ray leaves the bounds.
[[nodiscard]] inline bool entry_leaf(const PluckerLayout& layout, const Ray& ray, const WalkRay& walk_ray,
                                     std::uint32_t& address, float& walk_end) {
    const OctreeCube& cube = layout.cube;
    const Box3f& bounds = layout.bounds;
    float t_entry = -kInfinity, t_exit = kInfinity;
    int entry_axis = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const SlabInterval slab =
            slab_interval(bounds.lo[axis], bounds.hi[axis], ray.origin[axis], 1.0f / ray.direction[axis]);
        if (slab.near_t > t_entry) t_entry = slab.near_t, entry_axis = axis;
        t_exit = std::min(t_exit, slab.far_t);
    }
    if (!(std::max(t_entry, ray.tnear) <= std::min(t_exit, ray.tfar))) return false;
    walk_end = t_exit;
    if (t_entry <= ray.tnear) {
        // Inside the bounds at tnear: descend from the root.
        const Vec3f p = ray.origin + ray.tnear * ray.direction;
        address = descend(layout, 0, 0, {0, 0, 0}, p, walk_ray);
        return true;
    }
    // The cube map of the face the ray enters by (the lower face when it moves up on that axis).
    const auto entry_up = walk_ray.up[static_cast<std::size_t>(entry_axis)];
    const int face = make_face(entry_axis, entry_up ? 0 : 1);
    const std::uint32_t level = layout.cube_map.level[static_cast<std::size_t>(face)];
    const int u = lower_in_face_axis(entry_axis), v = upper_in_face_axis(entry_axis);
    Vec3f p = ray.origin + t_entry * ray.direction;
    p[entry_axis] = entry_up ? bounds.lo[entry_axis] : bounds.hi[entry_axis];
    const std::uint32_t i = cell_index(cube, u, level, p[u], walk_ray.up[static_cast<std::size_t>(u)]);
    const std::uint32_t j = cell_index(cube, v, level, p[v], walk_ray.up[static_cast<std::size_t>(v)]);
    const std::uint32_t texel =
        layout.cube_map.texels[layout.cube_map.offset[static_cast<std::size_t>(face)] + i + (j << level)];
    if (!(texel & kInnerBit)) {
        address = texel;
        return true;
    }
    // A texel over several deeper leaves (the cube map stops at level 10): descend from its cell, of the
    // face's layer (layout.cpp's face_layers).
    std::array<std::uint32_t, 3> coordinates{};
    coordinates[static_cast<std::size_t>(entry_axis)] =
        cell_index(cube, entry_axis, level, p[entry_axis], entry_up);
    coordinates[static_cast<std::size_t>(u)] = i;
    coordinates[static_cast<std::size_t>(v)] = j;
    address = descend(layout, texel & kAddressMask, static_cast<int>(level), coordinates, p, walk_ray);
    return true;
}

// EXIT-FACE (section 4.2.1): Pi_a(V) = (d x (V - o))_a against the three edges through the exit vertex V
// (equations 4-5 as one cross product: 6 products, 6 differences), packed by equation (6) and looked up by
// equation (8). `to_exit_vertex` = V - o.
[[nodiscard]] inline int exit_face(const WalkRay& ray, const Vec3f& to_exit_vertex) {
    const Vec3d products = cross(ray.direction, Vec3d(to_exit_vertex));
    const int pattern = (products.x > 0.0) | (products.y > 0.0) << 1 | (products.z > 0.0) << 2;
    return kExitFace[static_cast<std::size_t>(ray.octant)][static_cast<std::size_t>(pattern)];
}

// The sub-face (section 4.2.2) through which the ray crosses `face`, from the products against the lines
// through the face's centre P along the in-face axes (equations 9-10); `to_centre` = P - o. A product that
// is exactly 0 (the ray meets a median line) takes the octant's side (kQuadrantTieBits).
[[nodiscard]] inline std::uint32_t sub_face(const WalkRay& ray, int face, const Vec3f& to_centre) {
    const Vec3d products = cross(ray.direction, Vec3d(to_centre));
    const int signs = (products.x > 0.0) | (products.y > 0.0) << 1 | (products.z > 0.0) << 2;
    const int zeros = (products.x == 0.0) | (products.y == 0.0) << 1 | (products.z == 0.0) << 2;
    const int pattern = signs | (zeros & ray.tie[static_cast<std::size_t>(face_axis(face))]);
    return kNeighbourQuadrant[static_cast<std::size_t>(face)][static_cast<std::size_t>(pattern)];
}

// Rounding bound of the exit test: the difference w_a rounded once (the product limit |d_a| is exact in
// double), within the margin of intersect_box (2 gamma(3)). Shrinks towards -inf, so that rounding never
// stops the walk early.
[[nodiscard]] inline float exit_lower_bound(float distance) {
    constexpr float shrink = 2.0f * gamma_bound(3);
    return distance * (distance > 0.0f ? 1.0f - shrink : 1.0f + shrink);
}

// The walk, one leaf at a time: ENTRY, then after each leaf's test, EXIT-FACE and NEIGHBOR. kBalanced: every
// link is a leaf (the seed's 2:1 octree). Otherwise a link may name an inner cell, which is descended
// through the sub-face test on each level, and a walk stops after as many steps as there are words of
// cells: a walk that follows the ray never enters a leaf twice, and this bounds one that rounding made
// circle (the balanced walk needs no bound: docs/plucker-octree.md, "Termination").
template <bool kBalanced, class Boxes>
class Walker {
  public:
    struct State {
        WalkRay ray;
        std::uint32_t address = 0;   // the current leaf's record
        float walk_end = kInfinity;  // where the ray leaves the geometry's bounds (entry_leaf)
        std::size_t steps_left = 0;
    };

    Walker(const PluckerLayout& layout, const Boxes& boxes) : layout_(layout), boxes_(boxes) {}

    // ENTRY: false when the ray misses the root.
    [[nodiscard]] bool enter(const Ray& ray, State& state) const {
        state.ray = WalkRay(ray, layout_.cube);
        state.steps_left = layout_.cells.size();
        return entry_leaf(layout_, ray, state.ray, state.address, state.walk_end);
    }

    [[nodiscard]] const std::uint32_t* record(const State& state) const {
        return layout_.cells.data() + state.address;
    }

    // EXIT-FACE and NEIGHBOR of the current leaf, which depend on the ray and the cell alone: taken before
    // the leaf's triangles are tested, so that the next record, asked for here, arrives while they are.
    struct Exit {
        Vec3f to_exit_vertex;  // V - o
        int face = 0;
        float ahead = 0.0f;        // how far the exit plane lies ahead of the origin along its axis
        std::uint32_t link = 0;    // the neighbour across the exit, when there is one
        bool leaves_root = false;  // the exit face lies on the root's boundary
    };

    [[nodiscard]] Exit exit(const State& state) const {
        constexpr std::uint32_t kHeader = header_words(Boxes::kStored);
        const std::uint32_t* leaf = layout_.cells.data() + state.address;
        const WalkRay& ray = state.ray;
        const Vec3f& o = ray.origin;
        Exit exit;
        // EXIT-FACE
        const auto cell = boxes_.read(leaf + kBoxWord);
        exit.to_exit_vertex = {boxes_.exit_plane(cell, 0, ray.up[0]) - o.x,
                               boxes_.exit_plane(cell, 1, ray.up[1]) - o.y,
                               boxes_.exit_plane(cell, 2, ray.up[2]) - o.z};
        const Vec3f& w = exit.to_exit_vertex;
        exit.face = exit_face(ray, w);
        const int axis = face_axis(exit.face);
        exit.ahead = ray.up[static_cast<std::size_t>(axis)] ? w[axis] : -w[axis];
        // NEIGHBOR: the sub-face test only for four neighbours. The seed computes it for one neighbour too
        // and multiplies the index by count / 4 to save a branch (equation 10 and 5.3.2), which suits a GPU;
        // on the CPU the predicted branch is 15% faster over the canonical view (docs/plucker-octree.md).
        const std::uint32_t ends = leaf[kHeader - 1];
        const std::uint32_t start = neighbour_start(ends, exit.face);
        const std::uint32_t count = neighbour_end(ends, exit.face) - start;
        if (count == 0) {
            exit.leaves_root = true;
            return exit;
        }
        exit.link = leaf[kHeader + start];
        if (count == 4) {
            exit.link = leaf[kHeader + start +
                             sub_face(ray, exit.face,
                                      {axis == 0 ? w.x : boxes_.mid(cell, 0) - o.x,
                                       axis == 1 ? w.y : boxes_.mid(cell, 1) - o.y,
                                       axis == 2 ? w.z : boxes_.mid(cell, 2) - o.z})];
        }
        __builtin_prefetch(layout_.cells.data() + (exit.link & kAddressMask));
        return exit;
    }

    // After the current leaf was tested and the search interval ends at `limit`: moves across `exit` to
    // the next leaf, or returns false when the walk is over (the interval ends within this leaf, or the ray
    // leaves the root).
    template <bool kCount>
    [[nodiscard]] bool advance(State& state, const Exit& exit, float limit,
                               TraversalCounters* counters) const {
        const WalkRay& ray = state.ray;
        const int axis = face_axis(exit.face);
        // Done once the search interval ends before this leaf's exit: limit <= (V_a - o_a) / d_a, written
        // without a division (w_a has the sign of the direction when the exit lies ahead), the product exact
        // in double (in float, a denormal |d_a| made it 0 for a limit beyond an exit at t = 0).
        // The interval also ends where the ray leaves the geometry's bounds.
        const float end = std::min(limit, state.walk_end);
        if (static_cast<double>(end) * ray.abs_direction[axis] <= exit_lower_bound(exit.ahead)) return false;
        if (exit.leaves_root) return false;
        std::uint32_t link = exit.link;
        if constexpr (!kBalanced) {
            // A same-level inner cell: descend it, each level by the sub-face test on its face (the exit
            // plane is the same), to the child on the near side of the face.
            if (--state.steps_left == 0) return false;
            const std::uint32_t* cells = layout_.cells.data();
            const Vec3f& w = exit.to_exit_vertex;
            const Vec3f& o = ray.origin;
            const std::uint32_t near_bit = ray.up[static_cast<std::size_t>(axis)] ? 0u : 1u;
            const int u = lower_in_face_axis(axis), v = upper_in_face_axis(axis);
            while (link & kInnerBit) {
                const std::uint32_t* inner = cells + (link & kAddressMask);
                if constexpr (kCount) ++counters->nodes_visited;
                const auto inner_cell = boxes_.read(inner);
                const std::uint32_t inner_q = sub_face(ray, exit.face,
                                                       {axis == 0 ? w.x : boxes_.mid(inner_cell, 0) - o.x,
                                                        axis == 1 ? w.y : boxes_.mid(inner_cell, 1) - o.y,
                                                        axis == 2 ? w.z : boxes_.mid(inner_cell, 2) - o.z});
                const std::uint32_t child = near_bit << axis | (inner_q & 1u) << u | (inner_q >> 1) << v;
                link = inner[box_words(Boxes::kStored) + child];
            }
        }
        state.address = link;
        return true;
    }

    // Both steps after the leaf's test, for a caller that has no work to overlap with them.
    template <bool kCount>
    [[nodiscard]] bool advance(State& state, float limit, TraversalCounters* counters) const {
        return advance<kCount>(state, exit(state), limit, counters);
    }

  private:
    const PluckerLayout& layout_;
    const Boxes& boxes_;
};

// The whole walk of one ray (section 4.2.3). visit_leaf(record, limit) tests the leaf whose record starts at
// `record` and returns the new end of the search interval (the closest hit so far, or tfar); a value below
// tnear ends the walk (any hit).
template <bool kBalanced, bool kCount, class Boxes, class LeafVisitor>
void walk(const PluckerLayout& layout, const Boxes& boxes, const Ray& ray, LeafVisitor&& visit_leaf,
          TraversalCounters* counters) {
    const Walker<kBalanced, Boxes> walker(layout, boxes);
    typename Walker<kBalanced, Boxes>::State state;
    if (!walker.enter(ray, state)) return;
    float limit = ray.tfar;
    while (true) {
        const auto exit = walker.exit(state);
        // LEAF
        if constexpr (kCount) ++counters->nodes_visited;
        limit = visit_leaf(walker.record(state), limit);
        if (limit < ray.tnear) return;
        if (!walker.template advance<kCount>(state, exit, limit, counters)) return;
    }
}

// Calls body.template operator()<kBalanced>(boxes) with the layout's variant (2:1 rule or not, stored or
// computed cell boxes): the one branch on the layout, taken once per batch by every walk of it.
template <class Body>
void dispatch_layout(const PluckerLayout& layout, Body&& body) {
    const StoredBoxes stored{layout.boxes.data()};
    const ComputedBoxes computed{layout.cube, layout.tolerance};
    if (layout.options.balanced) {
        layout.options.stored_boxes ? body.template operator()<true>(stored)
                                    : body.template operator()<true>(computed);
    } else {
        layout.options.stored_boxes ? body.template operator()<false>(stored)
                                    : body.template operator()<false>(computed);
    }
}

}  // namespace lancer::plucker
