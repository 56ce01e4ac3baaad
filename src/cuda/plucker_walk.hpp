// The Pluecker octree walk of seed 000 section 4 (ENTRY 4.1, EXIT-FACE 4.2.1, NEIGHBOR 4.2.2, the loop of
// 4.2.3) for the device and the host, over the serialised arrays as the CPU lays them out (gpu_layout.hpp,
// PluckerView) and the tables in constant memory (PluckerTables). It is accel/plucker/walk.hpp's walk on its
// four layouts (with or without the 2:1 rule, stored or computed boxes), and its deviations from the seed
// (docs/plucker-octree.md), written without the standard library: the same operations (a step finds its exit
// before it tests the leaf's triangles, which changes no result), so that on the CPU it returns the `plucker`
// structure's hits bit for bit (tests/cuda/port_test.cpp). The seed's branch-free neighbour index (count / 4
// times the sub-face, equation 10 and 5.3.2) is kept as walk.hpp's branch: on a warp both cost about the
// same, and the branch keeps the two ports one reading (a profiler question, docs/cuda.md).
#pragma once

#include "core/vec3d.hpp"
#include "cuda/bvh_traversal.hpp"
#include "cuda/gpu_layout.hpp"
#include "cuda/triangle.hpp"

namespace lancer::gpu {

// Per-axis flags and the ray's row of the exit-face table are packed in words, not arrays: the step reads
// them at a per-thread axis or pattern, and on the GPU an array so indexed lives in local memory, and a
// constant-memory table read at per-lane addresses is served one address at a time.
struct PluckerWalkRay {
    Vec3f origin;
    Vec3d direction;  // in double: exact Pluecker products (walk.hpp's WalkRay)
    Vec3f abs_direction;
    std::uint32_t octant;      // bit `axis`: walk.hpp's up[axis], the side the ray moves to
    std::uint32_t tie_bits;    // bits 3 axis .. 3 axis + 2: walk.hpp's tie[axis]
    std::uint32_t exit_faces;  // bits 3 pattern .. 3 pattern + 2: exit_face[octant][pattern]

    LANCER_HOST_DEVICE std::uint32_t up(int axis) const { return (octant >> axis) & 1u; }
    LANCER_HOST_DEVICE int tie(int axis) const { return static_cast<int>((tie_bits >> (3 * axis)) & 7u); }
    LANCER_HOST_DEVICE int exit_face(int pattern) const {
        return static_cast<int>((exit_faces >> (3 * pattern)) & 7u);
    }
};

// OctreeCube::plane: the exact float of face i of the cells of `level` on `axis`.
LANCER_HOST_DEVICE inline float cube_plane(const PluckerView& octree, int axis, int level, std::uint32_t i) {
    return octree.cube_lo[axis] + octree.cube_size * (static_cast<float>(i) * inverse_power_of_two(level));
}

// layout.hpp's exit_plane_of: a cell's face, the root's faces grown by the tolerance.
LANCER_HOST_DEVICE inline float exit_plane(const PluckerView& octree, int axis, int level, std::uint32_t i) {
    if (i == 0) return cube_plane(octree, axis, 0, 0) - octree.tolerance;
    if (i == 1u << level) return cube_plane(octree, axis, 0, 1) + octree.tolerance;
    return cube_plane(octree, axis, level, i);
}

// The Pluecker layout a walk is compiled for: PluckerView::balanced and stored_boxes as template parameters,
// so that the step does not branch on them (walk.hpp's Walker and Boxes).
template <bool kBalancedLayout, bool kStoredBoxesLayout>
struct WalkLayout {
    static constexpr bool kBalanced = kBalancedLayout;
    static constexpr bool kStoredBoxes = kStoredBoxesLayout;
};
using SeedLayout = WalkLayout<true, true>;  // the default: 2:1 balanced, stored boxes

// The planes of a cell whose box word(s) start at `box_words` (walk.hpp's StoredBoxes and ComputedBoxes):
// from the boxes array (the seed's layout), or computed from the cell's integer coordinates and level
// (section 6, plucker.stored_boxes=false), which spares the step the box's load after the cell's.
struct CellPlanes {
    Vec3f exit;  // on each axis, the face the ray moves towards
    Vec3f mid;   // the mid planes, the faces the leaf's finer neighbours share (read with the exit planes,
                 // so that the sub-face test waits on no further load)
};

template <bool kStoredBoxes>
LANCER_HOST_DEVICE CellPlanes cell_planes(const PluckerView& octree, const std::uint32_t* box_words,
                                          const PluckerWalkRay& ray) {
    CellPlanes planes;
    if constexpr (kStoredBoxes) {
        const float* box = (octree.boxes + read_only(box_words))->planes.data();
        for (int axis = 0; axis < 3; ++axis) {
            planes.exit[axis] = read_only(box + axis + 6 * static_cast<int>(ray.up(axis)));
            planes.mid[axis] = read_only(box + 3 + axis);
        }
    } else {
        const std::uint32_t xy = read_only(box_words), z_level = read_only(box_words + 1);
        const std::uint32_t coordinates[3] = {xy & 0xFFFFu, xy >> 16, z_level & 0xFFFFu};
        const int level = static_cast<int>(z_level >> 16);
        for (int axis = 0; axis < 3; ++axis) {
            planes.exit[axis] = exit_plane(octree, axis, level, coordinates[axis] + ray.up(axis));
            planes.mid[axis] = cube_plane(octree, axis, level + 1, 2u * coordinates[axis] + 1u);
        }
    }
    return planes;
}

LANCER_HOST_DEVICE inline PluckerWalkRay make_walk_ray(const PluckerView& octree, const PluckerTables& tables,
                                                       const Ray& ray) {
    PluckerWalkRay walk_ray{ray.origin, Vec3d(ray.direction), {}, 0, 0, 0};
    for (int axis = 0; axis < 3; ++axis) {
        const float d = ray.direction[axis];
        walk_ray.abs_direction[axis] = abs_of(d);
        const bool moves = d != 0.0f;
        const float centre = octree.cube_lo[axis] + 0.5f * octree.cube_size;
        walk_ray.octant |= ((moves ? d > 0.0f : ray.origin[axis] < centre) ? 1u : 0u) << axis;
    }
    for (int axis = 0; axis < 3; ++axis)
        walk_ray.tie_bits |=
            static_cast<std::uint32_t>(
                tables.quadrant_tie[2 * axis + static_cast<int>(walk_ray.up(axis))][walk_ray.octant])
            << (3 * axis);
    for (int pattern = 0; pattern < 8; ++pattern)
        walk_ray.exit_faces |= static_cast<std::uint32_t>(tables.exit_face[walk_ray.octant][pattern])
                               << (3 * pattern);
    return walk_ray;
}

// walk.hpp's cell_index: the cell of `level` holding p on `axis`, ties to the ray's side, clamped.
LANCER_HOST_DEVICE inline std::uint32_t plucker_cell_index(const PluckerView& octree, int axis,
                                                           std::uint32_t level, float p, std::uint32_t up) {
    const std::uint32_t last = (1u << level) - 1u;
    const float scaled = (p - octree.cube_lo[axis]) / octree.cube_size * static_cast<float>(1u << level);
    std::uint32_t i =
        !(scaled > 0.0f) ? 0u : min_of(last, static_cast<std::uint32_t>(min_of(scaled, 65536.0f)));
    const int l = static_cast<int>(level);
    while (i > 0 && (up ? p < cube_plane(octree, axis, l, i) : p <= cube_plane(octree, axis, l, i)))
        --i;
    while (i < last &&
           (up ? p >= cube_plane(octree, axis, l, i + 1) : p > cube_plane(octree, axis, l, i + 1)))
        ++i;
    return i;
}

// walk.hpp's descend: the leaf holding p below tree cell `node`.
LANCER_HOST_DEVICE inline std::uint32_t plucker_descend(const PluckerView& octree, std::uint32_t node,
                                                        int level, std::uint32_t x, std::uint32_t y,
                                                        std::uint32_t z, const Vec3f& p,
                                                        const PluckerWalkRay& ray) {
    std::uint32_t coordinates[3] = {x, y, z};
    std::uint32_t word = read_only(octree.locate + node);
    while (word & 1u) {
        std::uint32_t child = 0;
        for (int axis = 0; axis < 3; ++axis) {
            const float mid = cube_plane(octree, axis, level + 1, 2u * coordinates[axis] + 1u);
            const std::uint32_t bit = ray.up(axis) ? p[axis] >= mid : p[axis] > mid;
            child |= bit << axis;
            coordinates[axis] = 2u * coordinates[axis] + bit;
        }
        node = (word >> 1) + child;
        word = read_only(octree.locate + node);
        ++level;
    }
    return word >> 1;
}

// walk.hpp's slab_interval.
struct SlabInterval {
    float near_t, far_t;
};
LANCER_HOST_DEVICE inline SlabInterval slab_interval(float lo, float hi, float origin, float inverse) {
    const float t_lo = (lo - origin) * inverse, t_hi = (hi - origin) * inverse;
    if (is_nan(t_lo) || is_nan(t_hi)) return {-kInfinity, kInfinity};
    return {min_of(t_lo, t_hi), widened_exit(max_of(t_lo, t_hi))};
}

// ENTRY (section 4.1): walk.hpp's entry_leaf, by the faces of the geometry's bounds.
LANCER_HOST_DEVICE inline bool plucker_entry_leaf(const PluckerView& octree, const Ray& ray,
                                                  const PluckerWalkRay& walk_ray, std::uint32_t& address,
                                                  float& walk_end) {
    float t_entry = -kInfinity, t_exit = kInfinity;
    int entry_axis = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const SlabInterval slab = slab_interval(octree.bounds_lo[axis], octree.bounds_hi[axis],
                                                ray.origin[axis], 1.0f / ray.direction[axis]);
        if (slab.near_t > t_entry) t_entry = slab.near_t, entry_axis = axis;
        t_exit = min_of(t_exit, slab.far_t);
    }
    if (!(max_of(t_entry, ray.tnear) <= min_of(t_exit, ray.tfar))) return false;
    walk_end = t_exit;
    if (t_entry <= ray.tnear) {
        const Vec3f p = ray.origin + ray.tnear * ray.direction;
        address = plucker_descend(octree, 0, 0, 0, 0, 0, p, walk_ray);
        return true;
    }
    const std::uint32_t entry_up = walk_ray.up(entry_axis);
    const int face = 2 * entry_axis + (entry_up ? 0 : 1);
    const std::uint32_t level = octree.cube_map_level[face];
    const int u = entry_axis == 0 ? 1 : 0, v = entry_axis == 2 ? 1 : 2;  // the in-face axes, increasing
    Vec3f p = ray.origin + t_entry * ray.direction;
    p[entry_axis] = entry_up ? octree.bounds_lo[entry_axis] : octree.bounds_hi[entry_axis];
    const std::uint32_t i = plucker_cell_index(octree, u, level, p[u], walk_ray.up(u));
    const std::uint32_t j = plucker_cell_index(octree, v, level, p[v], walk_ray.up(v));
    const std::uint32_t texel = read_only(octree.texels + octree.cube_map_offset[face] + i + (j << level));
    if (!(texel & plucker::kInnerBit)) {
        address = texel;
        return true;
    }
    // The cell's coordinates: the face's layer on entry_axis, (i, j) on (u, v).
    const std::uint32_t layer = plucker_cell_index(octree, entry_axis, level, p[entry_axis], entry_up);
    const std::uint32_t x = entry_axis == 0 ? layer : i;
    const std::uint32_t y = entry_axis == 1 ? layer : (entry_axis == 0 ? i : j);
    const std::uint32_t z = entry_axis == 2 ? layer : j;
    address =
        plucker_descend(octree, texel & plucker::kAddressMask, static_cast<int>(level), x, y, z, p, walk_ray);
    return true;
}

// walk.hpp's exit_lower_bound: the exit distance shrunk by the rounding of the exit test.
LANCER_HOST_DEVICE inline float plucker_exit_lower_bound(float distance) {
    const float shrink = 2.0f * gamma_of(3);
    return distance * (distance > 0.0f ? 1.0f - shrink : 1.0f + shrink);
}

// walk.hpp's sub_face: the quadrant of `face` the ray crosses, from the products against the lines through
// the centre of the face (equations 9-10). `w` is the exit vertex minus the origin (its `axis` coordinate is
// the face's), `mid` the mid planes of the cell whose face is split.
LANCER_HOST_DEVICE inline std::uint32_t plucker_sub_face(const PluckerWalkRay& walk_ray,
                                                         const PluckerTables& tables, int face,
                                                         const Vec3f& w, const Vec3f& mid) {
    const int axis = face >> 1;
    const Vec3f& o = walk_ray.origin;
    const Vec3f to_centre(axis == 0 ? w.x : mid.x - o.x, axis == 1 ? w.y : mid.y - o.y,
                          axis == 2 ? w.z : mid.z - o.z);
    const Vec3d sub = cross(walk_ray.direction, Vec3d(to_centre));
    const int signs = (sub.x > 0.0) | (sub.y > 0.0) << 1 | (sub.z > 0.0) << 2;
    const int zeros = (sub.x == 0.0) | (sub.y == 0.0) << 1 | (sub.z == 0.0) << 2;
    return tables.neighbour_quadrant[face][signs | (zeros & walk_ray.tie(axis))];
}

// The closest hit of one ray (ties to the smaller primitive index), a miss for an invalid ray. Triangles
// only: the caller refuses layouts with spheres (CudaTracer, tests), and compiles the walk for the octree's
// layout (Layout::kBalanced is octree.balanced, Layout::kStoredBoxes octree.stored_boxes).
template <class TriangleTestT, class Layout, class Steps = NoSteps>
LANCER_HOST_DEVICE Hit trace_plucker(const PluckerView& octree, const PluckerTables& tables, const Ray& ray,
                                     Steps&& steps = {}) {
    Hit best;
    if (!is_valid_ray(ray)) return best;
    const PluckerWalkRay walk_ray = make_walk_ray(octree, tables, ray);
    std::uint32_t address;
    float walk_end;
    if (!plucker_entry_leaf(octree, ray, walk_ray, address, walk_end)) return best;
    const typename TriangleTestT::RayData triangle_ray(ray);
    constexpr std::uint32_t kHeader = plucker::header_words(Layout::kStoredBoxes);
    const Vec3f& o = walk_ray.origin;
    // Without the 2:1 rule a walk is bounded by the number of cell words (walk.hpp's Walker).
    std::uint32_t steps_left = octree.cell_words;
    while (true) {
        // LEAF. The exit face and the link through it do not depend on the leaf's triangles, so they are
        // found first and the triangles tested after: the box-and-link loads and the triangle loads are then
        // in flight together, and only the exit test waits for both (walk.hpp's order, with the same
        // operations, would wait on the triangles, then the box, then the link).
        steps.step();
        const std::uint32_t* leaf = octree.cells + address;
        const plucker::PluckerPrimitive* triangles =
            octree.primitives + read_only(leaf + plucker::kTriangleOffset);
        const std::uint32_t triangle_count = read_only(leaf + plucker::kTriangleCount);
        if (triangle_count != 0) prefetch_line(triangles);  // the triangles' first line while the box loads
        const CellPlanes planes =
            cell_planes<Layout::kStoredBoxes>(octree, leaf + plucker::kBoxWord, walk_ray);
        const std::uint32_t ends = read_only(leaf + kHeader - 1);
        // EXIT-FACE (4.2.1): three Pluecker products against the edges through the exit vertex.
        const Vec3f w = planes.exit - o;
        const Vec3d products = cross(walk_ray.direction, Vec3d(w));
        const int pattern = (products.x > 0.0) | (products.y > 0.0) << 1 | (products.z > 0.0) << 2;
        const int face = walk_ray.exit_face(pattern);
        const int axis = face >> 1;
        // NEIGHBOR (4.2.2): the sub-face test only when four neighbours share the face; none on the root's
        // boundary.
        const std::uint32_t start = plucker::neighbour_start(ends, face);
        const std::uint32_t neighbours = plucker::neighbour_end(ends, face) - start;
        std::uint32_t next = 0;
        if (neighbours != 0) {
            const std::uint32_t link_index =
                start + (neighbours == 4 ? plucker_sub_face(walk_ray, tables, face, w, planes.mid) : 0u);
            next = read_only(leaf + kHeader + link_index);
        }
        intersect_leaf<TriangleTestT>(triangles, triangle_count, triangle_ray, ray, best);
        // The walk ends at a hit before the exit face, where the ray leaves the bounds, or at the root's
        // boundary.
        const float limit = min_of(best.prim >= 0 ? best.t : ray.tfar, walk_end);
        const float ahead = walk_ray.up(axis) ? w[axis] : -w[axis];
        if (static_cast<double>(limit) * walk_ray.abs_direction[axis] <= plucker_exit_lower_bound(ahead) ||
            neighbours == 0)
            return best;
        if constexpr (!Layout::kBalanced) {
            // A same-level inner cell: descend it, each level by the sub-face test on its face (the exit
            // plane is the same), to the child on the near side of the face.
            if (--steps_left == 0) return best;
            const std::uint32_t near_bit = walk_ray.up(axis) ? 0u : 1u;
            const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;  // the in-face axes, increasing
            while (next & plucker::kInnerBit) {
                const std::uint32_t* inner = octree.cells + (next & plucker::kAddressMask);
                steps.step();
                const CellPlanes inner_planes = cell_planes<Layout::kStoredBoxes>(octree, inner, walk_ray);
                const std::uint32_t quadrant = plucker_sub_face(walk_ray, tables, face, w, inner_planes.mid);
                const std::uint32_t child = near_bit << axis | (quadrant & 1u) << u | (quadrant >> 1) << v;
                next = read_only(inner + plucker::box_words(Layout::kStoredBoxes) + child);
            }
        }
        address = next;
    }
}

}  // namespace lancer::gpu
