#include "lancer/views.hpp"

#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <string>

namespace lancer {
namespace {

// The PCG hash of Jarzynski & Olano 2020 ("Hash Functions for GPU Rendering"), as VIEWS.md writes it, in
// wrapping uint32 arithmetic.
[[nodiscard]] std::uint32_t pcg_hash(std::uint32_t x) {
    const std::uint32_t state = x * 747796405u + 2891336453u;
    const std::uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// The unit geometric normal of the primitive hit at `point`, facing against `direction`.
[[nodiscard]] Vec3f facing_normal(const Geometry& geometry, const Hit& hit, Vec3f point, Vec3f direction) {
    const auto prim = static_cast<std::size_t>(hit.prim);
    Vec3f normal;
    if (prim < geometry.triangles.size()) {
        normal = normalize(geometry.triangles[prim].geometric_normal());
    } else {
        normal = normalize(point - geometry.spheres[prim - geometry.triangles.size()].center);
    }
    return dot(normal, direction) < 0.0f ? normal : -normal;
}

// A cosine-weighted direction about the unit normal n, from two uniform numbers in [0, 1), in the basis of
// Duff et al. 2017 ("Building an Orthonormal Basis, Revisited", listing 3).
[[nodiscard]] Vec3f cosine_direction(Vec3f n, float u1, float u2) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    const Vec3f t1(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    const Vec3f t2(b, sign + n.y * n.y * a, -n.y);
    const float phi = 2.0f * std::numbers::pi_v<float> * u1, rho = std::sqrt(u2);
    return rho * std::cos(phi) * t1 + rho * std::sin(phi) * t2 + std::sqrt(1.0f - u2) * n;
}

}  // namespace

std::string_view secondary_view_name(SecondaryView view) {
    return view == SecondaryView::Diffuse ? "diffuse" : "shadow";
}

std::vector<Ray> secondary_view_rays(SecondaryView view, const Geometry& geometry,
                                     std::span<const Ray> primary, std::span<const Hit> hits) {
    if (primary.size() != hits.size())
        throw std::invalid_argument("secondary_view_rays: " + std::to_string(primary.size()) + " rays but " +
                                    std::to_string(hits.size()) + " hits");
    const Box3f bounds = geometry.bounds();
    const Vec3f centre = (bounds.lo + bounds.hi) * 0.5f;
    const float r = length(bounds.hi - bounds.lo) * 0.5f;
    const Vec3f light = centre + Vec3f(0.5f * r, 2.0f * r, 1.5f * r);
    constexpr float kUnit = 0x1p-24f;  // (h >> 8) * 2^-24: 24 random bits in [0, 1)
    std::vector<Ray> rays;
    for (std::size_t pixel = 0; pixel < hits.size(); ++pixel) {
        const Hit& hit = hits[pixel];
        if (!hit.hit()) continue;
        const Ray& ray = primary[pixel];
        const Vec3f point = ray.origin + hit.t * ray.direction;
        const Vec3f normal = facing_normal(geometry, hit, point, ray.direction);
        const Vec3f origin = point + (1e-4f * r) * normal;
        if (view == SecondaryView::Shadow) {
            rays.push_back({origin, light - origin, 0.0f, 1.0f - 1e-4f});
            continue;
        }
        for (std::uint32_t k = 0; k < 4; ++k) {
            const std::uint32_t a = pcg_hash(4u * static_cast<std::uint32_t>(pixel) + k), b = pcg_hash(a);
            const float u1 = static_cast<float>(a >> 8u) * kUnit, u2 = static_cast<float>(b >> 8u) * kUnit;
            rays.push_back({origin, cosine_direction(normal, u1, u2), 0.0f, kInfinity});
        }
    }
    return rays;
}

}  // namespace lancer
