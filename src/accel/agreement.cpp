#include "lancer/agreement.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace lancer {
namespace {

std::string describe(const Ray& ray, const Hit& expected, const Hit& actual, std::size_t index) {
    std::ostringstream text;
    text << "ray " << index << " o=(" << ray.origin.x << ", " << ray.origin.y << ", " << ray.origin.z
         << ") d=(" << ray.direction.x << ", " << ray.direction.y << ", " << ray.direction.z << ") ["
         << ray.tnear << ", " << ray.tfar << "]: expected prim " << expected.prim << " t " << expected.t
         << ", got prim " << actual.prim << " t " << actual.t;
    return text.str();
}

}  // namespace

std::string Agreement::summary() const {
    std::ostringstream text;
    text << rays << " rays, " << hits << " hits, " << ties << " ties, " << mismatches << " mismatches";
    if (mismatches > 0) text << "; first: " << first_mismatch;
    return text.str();
}

Agreement compare_hits(std::span<const Ray> rays, std::span<const Hit> expected,
                       std::span<const Hit> actual) {
    Agreement agreement;
    agreement.rays = rays.size();
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit& e = expected[i];
        const Hit& a = actual[i];
        bool same;
        if (!e.hit() || !a.hit()) {
            same = e.hit() == a.hit() && (a.hit() || (a.t == kInfinity && a.prim == -1));
        } else {
            same = std::fabs(e.t - a.t) <= 1e-5f * std::max(std::fabs(e.t), std::fabs(a.t));
            if (same && e.prim != a.prim) ++agreement.ties;
        }
        agreement.hits += e.hit() ? 1 : 0;
        if (!same && agreement.mismatches++ == 0) agreement.first_mismatch = describe(rays[i], e, a, i);
    }
    return agreement;
}

Agreement compare_occlusion(std::span<const Ray> rays, std::span<const Hit> expected,
                            std::span<const std::uint8_t> occluded) {
    Agreement agreement;
    agreement.rays = rays.size();
    for (std::size_t i = 0; i < rays.size(); ++i) {
        agreement.hits += expected[i].hit() ? 1 : 0;
        if (expected[i].hit() != (occluded[i] != 0) && agreement.mismatches++ == 0) {
            Hit as_hit;
            as_hit.prim = occluded[i] ? 0 : -1;
            agreement.first_mismatch = "occlusion " + describe(rays[i], expected[i], as_hit, i);
        }
    }
    return agreement;
}

}  // namespace lancer
