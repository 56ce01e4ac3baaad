// Queries beyond the closest hit, for the Python module's Open3D-style API (docs/python.md): every hit
// along a ray and the nearest point of the geometry, over a structure's own BVH where it has one (bvh,
// bvh_packet, bvh4, bvh8, bvh8_packet), else over a binary SAH BVH of the geometry built once.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer {

// The point of the geometry nearest to a query point.
struct NearestPoint {
    Vec3f point;
    float distance = kInfinity;
    std::int32_t prim = -1;    // global primitive index, -1 for an empty geometry
    float u = 0.0f, v = 0.0f;  // a triangle's barycentric coordinates of `point` (weights of v1 and v2)
};

class GeometryQueries {
  public:
    // Builds the BVH on `geometry`, whose arrays must outlive this object. Throws as Accel::build does.
    GeometryQueries(const Geometry& geometry, TriangleTest test);
    // Walks `accel`'s own tree, built on `geometry`, when it is a BVH (walks_accel), and builds one as above
    // otherwise. Both must outlive this object; an update of `accel` (a refit, a rebuild) is followed, as
    // the tree is read at each query.
    GeometryQueries(const Accel& accel, const Geometry& geometry, TriangleTest test);
    ~GeometryQueries();
    GeometryQueries(const GeometryQueries&) = delete;
    GeometryQueries& operator=(const GeometryQueries&) = delete;

    // Appends to `hits` every primitive the ray hits within [tnear, tfar], each once, by increasing t (ties
    // by primitive index), with the triangle test's t, u and v. An invalid ray (is_valid) hits nothing.
    // Two triangles that share an edge the ray crosses may both be hit (the watertight test guarantees at
    // least one).
    void all_hits(const Ray& ray, std::vector<Hit>& hits) const;

    // crossings[i]: the number of distinct t among the hits all_hits gives the ray {origins[i], direction, 0,
    // inf}, the surfaces it crosses (one where it passes through a shared vertex or edge), for occupancy's
    // parity; crossings holds at least origins.size() entries. The same counts bit for bit, on `threads`
    // threads as parallel_for takes them; from about one ray per four primitives by a grid of the primitives
    // seen along `direction` (accel/crossing_grid.hpp), whose rays test the triangles of their cell and walk
    // no tree. The grids of the last directions and the call's arrays are kept for the next calls (the grids
    // as long as the structure's geometry stays the same; at most as many bytes as its triangles; the arrays
    // for at most 2^22 rays, 160 MB), so that calls along the same directions neither build them again nor
    // fault in fresh memory. Safe to call from several threads.
    void count_crossings(const Vec3f& direction, std::span<const Vec3f> origins,
                         std::span<std::uint32_t> crossings, int threads) const;

    // The nearest point of any primitive to `p` (ties by primitive index), computed in double and rounded
    // once; a sphere's is on its surface along the direction from its centre (its centre itself for p there).
    [[nodiscard]] NearestPoint nearest_point(const Vec3f& p) const;

    // Whether the queries walk the structure they were given instead of a tree of their own.
    [[nodiscard]] bool walks_accel() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace lancer
