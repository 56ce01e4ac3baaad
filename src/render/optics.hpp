// The optics of the Whitted ray tree: mirror and Snell-Descartes directions (Ferreira & Mendoza 2011,
// sections 4.1 and 4.2), Fresnel's dielectric reflectance, the camera's sample positions, and secondary-ray
// origins moved off the surface they leave (the "Lancer de rayon" slides, "problème de précision"; Wächter &
// Binder 2019).
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <optional>

#include "lancer/vec.hpp"

namespace lancer {

// Ferreira & Mendoza 2011, 4.1: V = 2 (I.N) N - I for I the unit vector back along the incoming ray; with d =
// -I the direction of travel, V = d - 2 (d.N) N. Any side of the surface, any length of d.
[[nodiscard]] inline Vec3f reflect(Vec3f direction, Vec3f normal) {
    return direction - 2.0f * dot(direction, normal) * normal;
}

// Ferreira & Mendoza 2011, 4.2, Snell-Descartes n_i sin(theta_i) = n_t sin(theta_t): the refracted direction
// of the unit direction d arriving at a surface whose unit normal n faces the incoming side (d.n <= 0), with
// eta = n_i / n_t. Written with d = -I as
//   T = eta d + (eta cos(theta_i) - cos(theta_t)) n,  cos(theta_i) = -d.n,
//   cos(theta_t) = sqrt(1 - eta^2 (1 - cos^2(theta_i))),
// a unit vector. Past the critical angle asin(1 / eta) the square root has no real value: total internal
// reflection, nullopt.
[[nodiscard]] inline std::optional<Vec3f> refract(Vec3f direction, Vec3f normal, float eta) {
    const float cos_i = std::min(-dot(direction, normal), 1.0f);
    const float sin2_t = eta * eta * (1.0f - cos_i * cos_i);
    if (sin2_t > 1.0f) return std::nullopt;
    const float cos_t = std::sqrt(1.0f - sin2_t);
    return eta * direction + (eta * cos_i - cos_t) * normal;
}

// Fresnel's reflectance of unpolarised light at a dielectric interface, the mean of the s and p power
// reflectances (Born & Wolf; pbrt-v4 FrDielectric), for cos(theta_i) in [0, 1] and eta = n_i / n_t:
//   r_s = (eta cos_i - cos_t) / (eta cos_i + cos_t),  r_p = (cos_i - eta cos_t) / (cos_i + eta cos_t).
// 1 past the critical angle.
[[nodiscard]] inline float fresnel_dielectric(float cos_i, float eta) {
    const float sin2_t = eta * eta * (1.0f - cos_i * cos_i);
    if (sin2_t >= 1.0f) return 1.0f;
    const float cos_t = std::sqrt(1.0f - sin2_t);
    const float r_s = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const float r_p = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5f * (r_s * r_s + r_p * r_p);
}

// Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6
// (2019). The hit point p carries a rounding error proportional to the magnitude of its coordinates, so no
// single distance in scene units clears the surface everywhere. Each coordinate is moved along the unit
// normal n (pointing to the side the new ray leaves from) by 256 n_i units in the last place of that
// coordinate, an integer step on its bit pattern; coordinates within 1/32 of zero, where ulps vanish, move
// by the fixed 2^-16 n_i instead. The paper's constants, unchanged: they cover the few-ulp error of a point
// interpolated from a triangle's vertices (and of a sphere or plane point projected back onto the surface).
[[nodiscard]] inline Vec3f offset_ray_origin(Vec3f p, Vec3f n) {
    constexpr float kOriginBand = 1.0f / 32.0f;
    constexpr float kFloatScale = 1.0f / 65536.0f;
    constexpr float kIntScale = 256.0f;
    Vec3f moved;
    for (int axis = 0; axis < 3; ++axis) {
        const float coordinate = p[axis];
        if (std::fabs(coordinate) < kOriginBand) {
            moved[axis] = coordinate + kFloatScale * n[axis];
        } else {
            // Adding to the bit pattern of a negative float moves it away from zero: flip the step's sign.
            const auto ulps = static_cast<std::int32_t>(kIntScale * n[axis]);
            const std::int32_t bits = std::bit_cast<std::int32_t>(coordinate);
            moved[axis] = std::bit_cast<float>(bits + (coordinate < 0.0f ? -ulps : ulps));
        }
    }
    return moved;
}

// Position of sample s of n inside a pixel, in [0, 1)^2: the Hammersley set ((s + 1/2) / n, phi_2(s)), phi_2
// the base-2 radical inverse, with y shifted by 1 / (2n) so that one sample is the pixel centre. Its points
// are stratified, one in each of the n columns and in every dyadic row of 1 / n (for n a power of two), and
// deterministic: the same pattern in every pixel, whatever thread renders it.
struct PixelSample {
    float x, y;
};

[[nodiscard]] inline PixelSample pixel_sample(std::uint32_t s, std::uint32_t n) {
    std::uint32_t bits = s;  // reversed below: phi_2(s) = reverse_bits(s) / 2^32
    bits = (bits << 16) | (bits >> 16);
    bits = ((bits & 0x00ff00ffu) << 8) | ((bits & 0xff00ff00u) >> 8);
    bits = ((bits & 0x0f0f0f0fu) << 4) | ((bits & 0xf0f0f0f0u) >> 4);
    bits = ((bits & 0x33333333u) << 2) | ((bits & 0xccccccccu) >> 2);
    bits = ((bits & 0x55555555u) << 1) | ((bits & 0xaaaaaaaau) >> 1);
    double y = static_cast<double>(bits) * 0x1p-32 + 0.5 / n;
    if (y >= 1.0) y -= 1.0;
    return {static_cast<float>((s + 0.5) / n), static_cast<float>(y)};
}

}  // namespace lancer
