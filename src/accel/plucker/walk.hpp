// The walk of Portalez & Duguet 2016, section 4, one source for the CPU structures (plucker.cpp, packet.cpp)
// and the GPU kernel (cuda/plucker_walk.hpp): entry by the boundary cube map (4.1), exit face by three
// Plücker signs and a table (4.2.1), sub-face by two more signs and a table (4.2.2), the loop of 4.2.3.
// Phases in the code: ENTRY, LEAF, EXIT-FACE, NEIGHBOR. It deviates from the seed where an exact closest hit
// needs it: it goes on past the first leaf with a hit, descends the tree for rays that start inside, gives
// zero direction components a sign, and computes the Plücker products in double (docs/accel/plucker.md, "The
// walk", "Zero direction components", "The Plücker products").
#pragma once

#include <cstdint>

#include "accel/plucker/conventions.hpp"
#include "accel/plucker/layout.hpp"
#include "core/host_device.hpp"
#include "core/intersect.hpp"
#include "lancer/vec3d.hpp"

namespace lancer::plucker {

// The arrays a walk reads, as pointers: into a PluckerLayout on the CPU (view_of), into device memory on the
// GPU (cuda/flatten.cpp).
struct PluckerView {
    const std::uint32_t* cells = nullptr;
    const PluckerPrimitive* primitives = nullptr;
    const PluckerBox* boxes = nullptr;  // none without stored boxes
    const std::uint32_t* texels = nullptr;
    const std::uint32_t* locate = nullptr;
    OctreeCube cube;
    float tolerance = 0.0f;
    Box3f bounds;                  // PluckerLayout::bounds
    std::uint32_t cell_words = 0;  // the size of `cells`, which bounds a walk without the 2:1 rule
    std::uint32_t cube_map_level[6] = {};
    std::uint32_t cube_map_offset[6] = {};
    bool balanced = true;      // the layout's variant (PluckerLayoutOptions), which the caller compiles the
    bool stored_boxes = true;  // walk for (dispatch_layout)
};

[[nodiscard]] inline PluckerView view_of(const PluckerLayout& layout) {
    PluckerView view;
    view.cells = layout.cells.data();
    view.primitives = layout.primitives.data();
    view.boxes = layout.boxes.data();
    view.texels = layout.cube_map.texels.data();
    view.locate = layout.locate.data();
    view.cube = layout.cube;
    view.tolerance = layout.tolerance;
    view.bounds = layout.bounds;
    view.cell_words = static_cast<std::uint32_t>(layout.cells.size());  // cell addresses are 31-bit words
    for (std::size_t face = 0; face < 6; ++face) {
        view.cube_map_level[face] = layout.cube_map.level[face];
        view.cube_map_offset[face] = layout.cube_map.offset[face];
    }
    view.balanced = layout.options.balanced;
    view.stored_boxes = layout.options.stored_boxes;
    return view;
}

// Portalez & Duguet's tables (2016, equations 8 and 9) and the tie bits of conventions.hpp as one plain
// struct: the GPU copies it to constant memory (section 5.2), where a warp reading one entry is served in one
// broadcast.
struct PluckerTables {
    std::uint8_t exit_face[8][8];
    std::uint8_t neighbour_quadrant[6][8];
    std::uint8_t quadrant_tie[6][8];
};

inline constexpr PluckerTables kTables = [] {
    PluckerTables tables{};
    for (std::size_t octant = 0; octant < 8; ++octant)
        for (std::size_t pattern = 0; pattern < 8; ++pattern)
            tables.exit_face[octant][pattern] = kExitFace[octant][pattern];
    for (std::size_t face = 0; face < 6; ++face) {
        for (std::size_t pattern = 0; pattern < 8; ++pattern) {
            tables.neighbour_quadrant[face][pattern] = kNeighbourQuadrant[face][pattern];
            tables.quadrant_tie[face][pattern] = kQuadrantTieBits[face][pattern];
        }
    }
    return tables;
}();

// The ray as the walk sees it. Per-axis flags and the ray's row of the exit-face table are packed in words:
// the step reads them at a per-ray axis or pattern, and on the GPU an array so indexed lives in local memory.
struct WalkRay {
    Vec3f origin;
    // The direction in double, for the Plücker products d x w with w = P - o (exit_face, sub_face): each
    // product of two floats is exact in double, and one subtraction keeps the exact sign, so every sign is
    // that of the exact product for the computed w, whatever the magnitudes (no overflow at 2^128, no
    // underflow at 2^-149).
    Vec3d direction{0.0, 0.0, 0.0};
    Vec3f abs_direction;  // |d|, for the exit distance
    std::uint32_t octant =
        0;  // the exit vertex: bit `axis` set when the ray leaves cells by their upper face
    std::uint32_t tie_bits = 0;    // bits 3 axis to 3 axis + 2: kQuadrantTieBits of the exit face on `axis`
    std::uint32_t exit_faces = 0;  // bits 3 pattern to 3 pattern + 2: kExitFace[octant][pattern]

    WalkRay() = default;
    // A zero direction component takes the side of the root's centre the origin is not on, so that the ray
    // has an exit vertex (docs/accel/plucker.md, "Zero direction components").
    LANCER_HOST_DEVICE WalkRay(const Ray& ray, const OctreeCube& cube, const PluckerTables& tables)
        : origin(ray.origin), direction(ray.direction), abs_direction(magnitude(ray.direction)) {
        for (int axis = 0; axis < 3; ++axis) {
            const float d = ray.direction[axis];
            const bool moves = d != 0.0f;
            const float centre = cube.lo[axis] + 0.5f * cube.size;
            octant |= ((moves ? d > 0.0f : ray.origin[axis] < centre) ? 1u : 0u) << axis;
        }
        for (int axis = 0; axis < 3; ++axis)
            tie_bits |= static_cast<std::uint32_t>(
                            tables.quadrant_tie[make_face(axis, static_cast<int>(up(axis)))][octant])
                        << (3 * axis);
        for (int pattern = 0; pattern < 8; ++pattern)
            exit_faces |= static_cast<std::uint32_t>(tables.exit_face[octant][pattern]) << (3 * pattern);
    }

    // 1 when the ray leaves cells through their upper face on `axis`.
    [[nodiscard]] LANCER_HOST_DEVICE std::uint32_t up(int axis) const { return (octant >> axis) & 1u; }
    [[nodiscard]] LANCER_HOST_DEVICE int tie(int axis) const {
        return static_cast<int>((tie_bits >> (3 * axis)) & 7u);
    }
};

// EXIT-FACE (section 4.2.1): Pi_a(V) = (d x (V - o))_a against the three edges through the exit vertex V
// (equations 4-5 as one cross product: 6 products, 6 differences), packed by equation (6) and looked up by
// equation (8). `to_exit_vertex` = V - o.
[[nodiscard]] LANCER_HOST_DEVICE inline int exit_face(const WalkRay& ray, const Vec3f& to_exit_vertex) {
    const Vec3d products = cross(ray.direction, Vec3d(to_exit_vertex));
    const int pattern = (products.x > 0.0) | (products.y > 0.0) << 1 | (products.z > 0.0) << 2;
    return static_cast<int>((ray.exit_faces >> (3 * pattern)) & 7u);
}

// The sub-face (section 4.2.2) through which the ray crosses `face`, from the products against the lines
// through the face's centre P along the in-face axes (equations 9-10); `to_centre` = P - o. A product that
// is exactly 0 (the ray meets a median line) takes the octant's side (kQuadrantTieBits).
[[nodiscard]] LANCER_HOST_DEVICE inline std::uint32_t sub_face(const WalkRay& ray,
                                                               const PluckerTables& tables, int face,
                                                               const Vec3f& to_centre) {
    const Vec3d products = cross(ray.direction, Vec3d(to_centre));
    const int signs = (products.x > 0.0) | (products.y > 0.0) << 1 | (products.z > 0.0) << 2;
    const int zeros = (products.x == 0.0) | (products.y == 0.0) << 1 | (products.z == 0.0) << 2;
    return tables.neighbour_quadrant[face][signs | (zeros & ray.tie(face_axis(face)))];
}

// Rounding bound of the exit test: the difference w_a rounded once (the product limit |d_a| is exact in
// double), within the margin of intersect_box (2 gamma(3)). Shrinks towards -inf, so that rounding never
// stops the walk early.
[[nodiscard]] LANCER_HOST_DEVICE inline float exit_lower_bound(float distance) {
    constexpr float shrink = 2.0f * gamma_bound(3);
    return distance * (distance > 0.0f ? 1.0f - shrink : 1.0f + shrink);
}

// The interval of one slab [lo, hi] along a ray, the exit widened by its rounding. NaN (the origin on a
// plane, no motion along the axis): the ray runs inside the closed slab.
struct SlabInterval {
    float near_t, far_t;
};
[[nodiscard]] LANCER_HOST_DEVICE inline SlabInterval slab_interval(float lo, float hi, float origin,
                                                                   float inverse) {
    const float t_lo = (lo - origin) * inverse, t_hi = (hi - origin) * inverse;
    if (is_nan(t_lo) || is_nan(t_hi)) return {-kInfinity, kInfinity};
    return {min_of(t_lo, t_hi), widened_slab_exit(max_of(t_lo, t_hi))};
}

// The leaf holding point p, from tree cell `node` of the given level and coordinates (the root, or a cube
// map texel's cell), with the tie rule of cell_index.
[[nodiscard]] LANCER_HOST_DEVICE inline std::uint32_t descend(const PluckerView& view, std::uint32_t node,
                                                              int level, const std::uint32_t (&start)[3],
                                                              const Vec3f& p, const WalkRay& ray) {
    std::uint32_t coordinates[3] = {start[0], start[1], start[2]};
    std::uint32_t word = read_only(view.locate + node);
    while (word & 1u) {
        std::uint32_t child = 0;
        for (int axis = 0; axis < 3; ++axis) {
            const float mid = view.cube.plane(axis, level + 1, 2u * coordinates[axis] + 1u);
            const std::uint32_t bit = ray.up(axis) ? p[axis] >= mid : p[axis] > mid;
            child |= bit << axis;
            coordinates[axis] = 2u * coordinates[axis] + bit;
        }
        node = (word >> 1) + child;
        word = read_only(view.locate + node);
        ++level;
    }
    return word >> 1;
}

// ENTRY (Portalez & Duguet 2016, section 4.1): the first leaf along [tnear, tfar], or false when the ray
// misses the geometry's bounds (grown by the scene's tolerance, as every structure's boxes:
// docs/numerical-contract.md). The seed enters by the root's faces; the root is a cube anchored at the
// bounds' lower corner, and the walk starts and ends at the bounds instead, so that it does not cross the
// root's empty rest (PluckerLayout:: bounds). walk_end: where the ray leaves the bounds.
[[nodiscard]] LANCER_HOST_DEVICE inline bool entry_leaf(const PluckerView& view, const Ray& ray,
                                                        const WalkRay& walk_ray, std::uint32_t& address,
                                                        float& walk_end) {
    const OctreeCube& cube = view.cube;
    const Box3f& bounds = view.bounds;
    float t_entry = -kInfinity, t_exit = kInfinity;
    int entry_axis = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const SlabInterval slab =
            slab_interval(bounds.lo[axis], bounds.hi[axis], ray.origin[axis], 1.0f / ray.direction[axis]);
        if (slab.near_t > t_entry) t_entry = slab.near_t, entry_axis = axis;
        t_exit = min_of(t_exit, slab.far_t);
    }
    if (!(max_of(t_entry, ray.tnear) <= min_of(t_exit, ray.tfar))) return false;
    walk_end = t_exit;
    if (t_entry <= ray.tnear) {
        // Inside the bounds at tnear: descend from the root.
        const Vec3f p = ray.origin + ray.tnear * ray.direction;
        address = descend(view, 0, 0, {0, 0, 0}, p, walk_ray);
        return true;
    }
    // The cube map of the face the ray enters by (the lower face when it moves up on that axis).
    const std::uint32_t entry_up = walk_ray.up(entry_axis);
    const int face = make_face(entry_axis, entry_up ? 0 : 1);
    const std::uint32_t level = view.cube_map_level[face];
    const int u = lower_in_face_axis(entry_axis), v = upper_in_face_axis(entry_axis);
    Vec3f p = ray.origin + t_entry * ray.direction;
    p[entry_axis] = entry_up ? bounds.lo[entry_axis] : bounds.hi[entry_axis];
    const std::uint32_t i = cell_index(cube, u, level, p[u], walk_ray.up(u));
    const std::uint32_t j = cell_index(cube, v, level, p[v], walk_ray.up(v));
    const std::uint32_t texel = read_only(view.texels + view.cube_map_offset[face] + i + (j << level));
    if (!(texel & kInnerBit)) {
        address = texel;
        return true;
    }
    // A texel over several deeper leaves (the cube map stops at level 10): descend from its cell, of the
    // face's layer (build.cpp's face_layers) on entry_axis and (i, j) on (u, v).
    std::uint32_t coordinates[3];
    coordinates[entry_axis] = cell_index(cube, entry_axis, level, p[entry_axis], entry_up);
    coordinates[u] = i;
    coordinates[v] = j;
    address = descend(view, texel & kAddressMask, static_cast<int>(level), coordinates, p, walk_ray);
    return true;
}

// What a CPU walk counts (a walk calls step() for each cell it enters: the leaves and the inner cells it
// descends): with kCount, each one as a node visited.
template <bool kCount>
struct CellCounter {
    TraversalCounters& counters;
    void step() const {
        if constexpr (kCount) ++counters.nodes_visited;
    }
};

// The walk, one leaf at a time: ENTRY, then after each leaf's test, EXIT-FACE and NEIGHBOR. kBalanced: every
// link is a leaf (the seed's 2:1 octree). Otherwise a link may name an inner cell, which is descended
// through the sub-face test on each level, and a walk stops after as many steps as there are words of
// cells: a walk that follows the ray never enters a leaf twice, and this bounds one that rounding made
// circle (the balanced walk needs no bound: docs/accel/plucker.md, "Termination"). kStoredBoxes: a cell's
// planes are read from its stored box (the seed's layout), else computed from its integer coordinates and
// level (section 6), which spares the step the box's load after the cell's.
template <bool kBalanced, bool kStoredBoxes>
class Walker {
  public:
    struct State {
        WalkRay ray;
        std::uint32_t address = 0;   // the current leaf's record
        float walk_end = kInfinity;  // where the ray leaves the geometry's bounds (entry_leaf)
        std::uint32_t steps_left = 0;
    };

    LANCER_HOST_DEVICE Walker(const PluckerView& view, const PluckerTables& tables)
        : view_(view), tables_(tables) {}

    // ENTRY: false when the ray misses the bounds.
    [[nodiscard]] LANCER_HOST_DEVICE bool enter(const Ray& ray, State& state) const {
        state.ray = WalkRay(ray, view_.cube, tables_);
        state.steps_left = view_.cell_words;
        return entry_leaf(view_, ray, state.ray, state.address, state.walk_end);
    }

    [[nodiscard]] LANCER_HOST_DEVICE const std::uint32_t* record(const State& state) const {
        return view_.cells + state.address;
    }

    // EXIT-FACE and NEIGHBOR of the current leaf, which depend on the ray and the cell alone: taken before
    // the leaf's triangles are tested, so that the loads of the cell's planes and of the next link are in
    // flight while they are.
    struct Exit {
        Vec3f to_exit_vertex;  // V - o
        int face = 0;
        float ahead = 0.0f;        // how far the exit plane lies ahead of the origin along its axis
        std::uint32_t link = 0;    // the neighbour across the exit, when there is one
        bool leaves_root = false;  // the exit face lies on the root's boundary
    };

    [[nodiscard]] LANCER_HOST_DEVICE Exit exit(const State& state) const {
        constexpr std::uint32_t kHeader = header_words(kStoredBoxes);
        const std::uint32_t* leaf = view_.cells + state.address;
        const WalkRay& ray = state.ray;
        Exit exit;
        // EXIT-FACE
        const CellPlanes planes = cell_planes(leaf + kBoxWord, ray);
        exit.to_exit_vertex = planes.exit - ray.origin;
        const Vec3f& w = exit.to_exit_vertex;
        exit.face = exit_face(ray, w);
        const int axis = face_axis(exit.face);
        exit.ahead = ray.up(axis) ? w[axis] : -w[axis];
        // NEIGHBOR: the sub-face test only for four neighbours. The seed computes it for one neighbour too
        // and multiplies the index by count / 4 to save a branch (equation 10 and 5.3.2), which suits a GPU;
        // on the CPU the predicted branch is 15% faster over the canonical view (docs/accel/plucker.md).
        const std::uint32_t ends = read_only(leaf + kHeader - 1);
        const std::uint32_t start = neighbour_start(ends, exit.face);
        const std::uint32_t count = neighbour_end(ends, exit.face) - start;
        if (count == 0) {
            exit.leaves_root = true;
            return exit;
        }
        const std::uint32_t index = start + (count == 4 ? sub_face_across(ray, exit, planes.mid) : 0u);
        exit.link = read_only(leaf + kHeader + index);
#if !defined(__CUDA_ARCH__)
        // The CPU asks for the next record now, so that it arrives while the leaf is tested; on the GPU the
        // other warps hide that wait (docs/cuda.md).
        prefetch_line(view_.cells + (exit.link & kAddressMask));
#endif
        return exit;
    }

    // After the current leaf was tested and the search interval ends at `limit`: moves across `exit` to
    // the next leaf, or returns false when the walk is over (the interval ends within this leaf, or the ray
    // leaves the root). Each inner cell descended is one step.
    template <class Steps>
    [[nodiscard]] LANCER_HOST_DEVICE bool advance(State& state, const Exit& exit, float limit,
                                                  Steps& steps) const {
        const WalkRay& ray = state.ray;
        const int axis = face_axis(exit.face);
        // Done once the search interval ends before this leaf's exit: limit <= (V_a - o_a) / d_a, written
        // without a division (w_a has the sign of the direction when the exit lies ahead), the product exact
        // in double (in float, a denormal |d_a| made it 0 for a limit beyond an exit at t = 0).
        // The interval also ends where the ray leaves the geometry's bounds.
        const float end = min_of(limit, state.walk_end);
        if (static_cast<double>(end) * ray.abs_direction[axis] <= exit_lower_bound(exit.ahead)) return false;
        if (exit.leaves_root) return false;
        std::uint32_t link = exit.link;
        if constexpr (!kBalanced) {
            // A same-level inner cell: descend it, each level by the sub-face test on its face (the exit
            // plane is the same), to the child on the near side of the face.
            if (--state.steps_left == 0) return false;
            const std::uint32_t near_bit = ray.up(axis) ? 0u : 1u;
            const int u = lower_in_face_axis(axis), v = upper_in_face_axis(axis);
            while (link & kInnerBit) {
                const std::uint32_t* inner = view_.cells + (link & kAddressMask);
                steps.step();
                const std::uint32_t quadrant = sub_face_across(ray, exit, cell_planes(inner, ray).mid);
                const std::uint32_t child = near_bit << axis | (quadrant & 1u) << u | (quadrant >> 1) << v;
                link = read_only(inner + box_words(kStoredBoxes) + child);
            }
        }
        state.address = link;
        return true;
    }

  private:
    // A cell's planes: on each axis the one the ray moves towards, and the mid planes, the faces its finer
    // neighbours share (read together, so that the sub-face test waits on no further load).
    struct CellPlanes {
        Vec3f exit;
        Vec3f mid;
    };

    // The planes of the cell whose box word(s) start at `words`.
    [[nodiscard]] LANCER_HOST_DEVICE CellPlanes cell_planes(const std::uint32_t* words,
                                                            const WalkRay& ray) const {
        CellPlanes planes;
        if constexpr (kStoredBoxes) {
            const float* box = view_.boxes[read_only(words)].planes.data();
            for (int axis = 0; axis < 3; ++axis) {
                planes.exit[axis] = read_only(box + axis + 6 * static_cast<int>(ray.up(axis)));
                planes.mid[axis] = read_only(box + 3 + axis);
            }
        } else {
            const std::uint32_t xy = read_only(words), z_level = read_only(words + 1);
            const std::uint32_t coordinates[3] = {xy & 0xFFFFu, xy >> 16, z_level & 0xFFFFu};
            const int level = static_cast<int>(z_level >> 16);
            for (int axis = 0; axis < 3; ++axis) {
                planes.exit[axis] =
                    exit_plane_of(view_.cube, view_.tolerance, axis, level, coordinates[axis] + ray.up(axis));
                planes.mid[axis] = view_.cube.plane(axis, level + 1, 2u * coordinates[axis] + 1u);
            }
        }
        return planes;
    }

    // The quadrant of the exit face the ray crosses, for a cell of that face with mid planes `mid`: the
    // face's centre is the exit plane on the face's axis and the mid planes on the others.
    [[nodiscard]] LANCER_HOST_DEVICE std::uint32_t sub_face_across(const WalkRay& ray, const Exit& exit,
                                                                   const Vec3f& mid) const {
        const int axis = face_axis(exit.face);
        const Vec3f& w = exit.to_exit_vertex;
        const Vec3f& o = ray.origin;
        return sub_face(
            ray, tables_, exit.face,
            {axis == 0 ? w.x : mid.x - o.x, axis == 1 ? w.y : mid.y - o.y, axis == 2 ? w.z : mid.z - o.z});
    }

    const PluckerView& view_;
    const PluckerTables& tables_;
};

// The whole walk of one ray (section 4.2.3). visit_leaf(record, limit) tests the leaf whose record starts at
// `record` and returns the new end of the search interval (the closest hit so far, or tfar); a value below
// tnear ends the walk (any hit). steps.step() is called for each cell entered.
template <bool kBalanced, bool kStoredBoxes, class LeafVisitor, class Steps>
LANCER_HOST_DEVICE void walk(const PluckerView& view, const PluckerTables& tables, const Ray& ray,
                             LeafVisitor&& visit_leaf, Steps& steps) {
    const Walker<kBalanced, kStoredBoxes> walker(view, tables);
    typename Walker<kBalanced, kStoredBoxes>::State state;
    if (!walker.enter(ray, state)) return;
    float limit = ray.tfar;
    while (true) {
        // The leaf's first triangles are asked for before its planes are read, so that both loads are in
        // flight together.
        const std::uint32_t* leaf = walker.record(state);
        if (read_only(leaf + kTriangleCount) != 0)
            prefetch_line(view.primitives + read_only(leaf + kTriangleOffset));
        const auto exit = walker.exit(state);
        // LEAF
        steps.step();
        limit = visit_leaf(leaf, limit);
        if (limit < ray.tnear) return;
        if (!walker.advance(state, exit, limit, steps)) return;
    }
}

// Calls body.template operator()<kBalanced, kStoredBoxes>() with the layout's variant: the one branch on the
// layout, taken once per batch by every walk of it.
template <class Body>
void dispatch_layout(const PluckerLayoutOptions& options, Body&& body) {
    if (options.balanced) {
        options.stored_boxes ? body.template operator()<true, true>()
                             : body.template operator()<true, false>();
    } else {
        options.stored_boxes ? body.template operator()<false, true>()
                             : body.template operator()<false, false>();
    }
}

}  // namespace lancer::plucker
