#include "lancer/camera.hpp"

#include <cmath>
#include <numbers>

namespace lancer {

PinholeCamera::PinholeCamera(const Camera& camera)
    : eye_(camera.eye),
      tan_half_fov_(std::tan(camera.vertical_fov_degrees * std::numbers::pi_v<float> / 360.0f)),
      aspect_(static_cast<float>(camera.width) / static_cast<float>(camera.height)),
      width_(camera.width),
      height_(camera.height) {
    // VIEWS.md: f = normalize(c - eye), x = normalize(cross(f, up)), y = cross(x, f).
    forward_ = normalize(camera.look_at - camera.eye);
    right_ = normalize(cross(forward_, camera.up));
    up_ = cross(right_, forward_);
}

// Inline: block_rays vectorizes only with them inlined (only this file calls them).
inline float PinholeCamera::film_u(float film_x) const {
    return (2.0f * film_x / static_cast<float>(width_) - 1.0f) * tan_half_fov_ * aspect_;
}

inline float PinholeCamera::film_v(float film_y) const {
    return (1.0f - 2.0f * film_y / static_cast<float>(height_)) * tan_half_fov_;
}

inline Vec3f PinholeCamera::direction(float u, float v) const {
    return normalize(forward_ + u * right_ + v * up_);
}

Ray PinholeCamera::generate(float film_x, float film_y) const {
    Ray ray;
    ray.origin = eye_;
    ray.direction = direction(film_u(film_x), film_v(film_y));
    return ray;
}

void PinholeCamera::block_rays(int x0, int y0, std::span<Ray, kBlockSide * kBlockSide> out) const {
    // u depends on the column only and v on the row only: 4 of each, not 16 (each a division).
    float u[kBlockSide], v[kBlockSide];
    for (int k = 0; k < kBlockSide; ++k) {
        u[k] = film_u(static_cast<float>(x0 + k) + 0.5f);
        v[k] = film_v(static_cast<float>(y0 + k) + 0.5f);
    }
    // Field by field: GCC vectorizes the loop across the 16 pixels then (a Ray copied whole stops it), and
    // each lane's operations are the scalar ones, so the rays are generate's bit for bit.
    for (int k = 0; k < kBlockSide * kBlockSide; ++k) {
        const Vec3f d = direction(u[k % kBlockSide], v[k / kBlockSide]);
        Ray& ray = out[static_cast<std::size_t>(k)];
        ray.origin.x = eye_.x, ray.origin.y = eye_.y, ray.origin.z = eye_.z;
        ray.direction.x = d.x, ray.direction.y = d.y, ray.direction.z = d.z;
        ray.tnear = 0.0f, ray.tfar = kInfinity;
    }
}

std::vector<Ray> PinholeCamera::pixel_centre_rays(int x0, int y0, int x1, int y1) const {
    std::vector<Ray> rays;
    rays.reserve(static_cast<std::size_t>(x1 - x0) * static_cast<std::size_t>(y1 - y0));
    for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x)
            rays.push_back(generate(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f));
    }
    return rays;
}

}  // namespace lancer
