// Queries beyond the closest hit, for the Python module's Open3D-style API (docs/python.md): every hit
// along a ray, over a binary SAH BVH of the geometry built once.
#pragma once

#include <memory>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer {

class GeometryQueries {
  public:
    // Builds the BVH on `geometry`, whose arrays must outlive this object. Throws as Accel::build does.
    GeometryQueries(const Geometry& geometry, TriangleTest test);
    ~GeometryQueries();
    GeometryQueries(const GeometryQueries&) = delete;
    GeometryQueries& operator=(const GeometryQueries&) = delete;

    // Appends to `hits` every primitive the ray hits within [tnear, tfar], each once, by increasing t (ties
    // by primitive index), with the triangle test's t, u and v. An invalid ray (is_valid) hits nothing.
    // Two triangles that share an edge the ray crosses may both be hit (the watertight test guarantees at
    // least one).
    void all_hits(const Ray& ray, std::vector<Hit>& hits) const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace lancer
