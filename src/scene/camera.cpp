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

Ray PinholeCamera::generate(float film_x, float film_y) const {
    const float u = (2.0f * film_x / static_cast<float>(width_) - 1.0f) * tan_half_fov_ * aspect_;
    const float v = (1.0f - 2.0f * film_y / static_cast<float>(height_)) * tan_half_fov_;
    Ray ray;
    ray.origin = eye_;
    ray.direction = normalize(forward_ + u * right_ + v * up_);
    return ray;
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
