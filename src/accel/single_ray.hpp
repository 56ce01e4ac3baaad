// What every structure that traces one ray at a time shares: the geometry and options it was built with,
// the build's time, and the two batch methods, made from one traversal the structure writes once:
//
//   template <bool kAnyHit, bool kCount, class TriangleTestT>
//   bool trace(const PreparedRay<TriangleTestT>& prepared, Hit& best, TraversalCounters& counts) const;
//
// Closest hit (kAnyHit false): the answer is left in `best`. Any hit: returns whether one was found.
// kCount: add the nodes and primitives visited to `counts`. The structure builds in
// build_from(geometry, options), which this class times. Accel::update rebuilds, unless the structure
// declares its own `UpdateReport update_from(const Geometry&)` (the BVHs' refit).
#pragma once

#include <chrono>
#include <cstdint>
#include <span>

#include "accel/primitive_intersect.hpp"
#include "lancer/accel.hpp"

namespace lancer {

template <class Derived>
class SingleRayAccel : public Accel {
  protected:
    void build_structure(const Geometry& geometry, const BuildOptions& options) final;
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const final;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const final;
    UpdateReport update_structure(const Geometry& geometry) final;
    [[nodiscard]] SingleRayWalk single_ray_walk() const final;
    // The update of a structure that declares none: a build with the same options.
    UpdateReport update_from(const Geometry& geometry) {
        const BuildOptions options = options_;
        build_structure(geometry, options);
        return {};
    }

    Geometry geometry_;
    BuildOptions options_;
    double build_ms_ = 0.0;

  private:
    // single_ray_walk's entries: the batch calls' body for one ray.
    template <class TriangleTestT>
    static void closest_one(const Accel& structure, const Ray& ray, Hit& best, TraversalCounters* counters);
    template <class TriangleTestT>
    static bool any_one(const Accel& structure, const Ray& ray, TraversalCounters* counters);
};

// Defined out of the class, so that they are not inline: each structure's source file, where its trace()
// is defined, instantiates them (`template class SingleRayAccel<GridAccel>;`), and its header declares that
// instantiation (`extern template`), so that no other file needs trace()'s definition.
template <class Derived>
void SingleRayAccel<Derived>::build_structure(const Geometry& geometry, const BuildOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    geometry_ = geometry;
    options_ = options;
    static_cast<Derived*>(this)->build_from(geometry, options);
    build_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

template <class Derived>
UpdateReport SingleRayAccel<Derived>::update_structure(const Geometry& geometry) {
    // Derived's update_from where it declares one, this class's otherwise.
    return static_cast<Derived*>(this)->update_from(geometry);
}

template <class Derived>
void SingleRayAccel<Derived>::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                              TraversalCounters* counters) const {
    const auto& self = static_cast<const Derived&>(*this);
    intersect_each(options_.triangle_test, rays, hits, counters,
                   [&]<class TriangleTestT, bool kCount>(const PreparedRay<TriangleTestT>& prepared,
                                                         Hit& best, TraversalCounters& counts) {
                       self.template trace<false, kCount>(prepared, best, counts);
                   });
}

template <class Derived>
void SingleRayAccel<Derived>::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                             TraversalCounters* counters) const {
    const auto& self = static_cast<const Derived&>(*this);
    occluded_each(options_.triangle_test, rays, occluded, counters,
                  [&]<class TriangleTestT, bool kCount>(const PreparedRay<TriangleTestT>& prepared,
                                                        TraversalCounters& counts) {
                      Hit unused;
                      return self.template trace<true, kCount>(prepared, unused, counts);
                  });
}

template <class Derived>
SingleRayWalk SingleRayAccel<Derived>::single_ray_walk() const {
    SingleRayWalk walk;
    dispatch_policies(options_.triangle_test, false, [&]<class TriangleTestT, bool>() {
        walk.closest = &SingleRayAccel::closest_one<TriangleTestT>;
        walk.any = &SingleRayAccel::any_one<TriangleTestT>;
    });
    return walk;
}

template <class Derived>
template <class TriangleTestT>
void SingleRayAccel<Derived>::closest_one(const Accel& structure, const Ray& ray, Hit& best,
                                          TraversalCounters* counters) {
    const auto& self = static_cast<const Derived&>(structure);
    const PreparedRay<TriangleTestT> prepared(ray);
    if (counters == nullptr) {
        TraversalCounters unused;
        self.template trace<false, false>(prepared, best, unused);
    } else {
        ++counters->rays;
        self.template trace<false, true>(prepared, best, *counters);
    }
}

template <class Derived>
template <class TriangleTestT>
bool SingleRayAccel<Derived>::any_one(const Accel& structure, const Ray& ray, TraversalCounters* counters) {
    const auto& self = static_cast<const Derived&>(structure);
    const PreparedRay<TriangleTestT> prepared(ray);
    Hit unused;
    if (counters == nullptr) {
        TraversalCounters uncounted;
        return self.template trace<true, false>(prepared, unused, uncounted);
    }
    ++counters->rays;
    return self.template trace<true, true>(prepared, unused, *counters);
}

}  // namespace lancer
