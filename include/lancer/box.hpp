// Axis-aligned bounding box.
#pragma once

#include <limits>

#include "lancer/vec.hpp"

namespace lancer {

struct Box3f {
    // Empty box: the identity of merge().
    Vec3f lo{std::numeric_limits<float>::infinity()};
    Vec3f hi{-std::numeric_limits<float>::infinity()};

    void extend(Vec3f p) { lo = min(lo, p), hi = max(hi, p); }
    void extend(const Box3f& b) { lo = min(lo, b.lo), hi = max(hi, b.hi); }
    [[nodiscard]] bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
    [[nodiscard]] Vec3f center() const { return (lo + hi) * 0.5f; }
    [[nodiscard]] Vec3f extent() const { return hi - lo; }
    [[nodiscard]] Box3f grown(float margin) const { return {lo - Vec3f(margin), hi + Vec3f(margin)}; }
    [[nodiscard]] float surface_area() const {
        if (empty()) return 0.0f;
        Vec3f e = extent();
        return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
    }
    [[nodiscard]] bool contains(Vec3f p) const {
        return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
    }
    // Whether `inner` lies inside, faces included; an empty `inner` lies inside any box.
    [[nodiscard]] bool contains(const Box3f& inner) const {
        return lo.x <= inner.lo.x && lo.y <= inner.lo.y && lo.z <= inner.lo.z && inner.hi.x <= hi.x &&
               inner.hi.y <= hi.y && inner.hi.z <= hi.z;
    }
};

}  // namespace lancer
