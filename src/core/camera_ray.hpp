// The pinhole camera's rays (shared/bench/VIEWS.md), one source for PinholeCamera (scene/camera.cpp) and the
// GPU's frame kernels (cuda/kernels.cu): the same operations in the same order give the same rays, bit for
// bit, with unfused products (g++ -ffp-contract=off, nvcc --fmad=false) and IEEE division and square root.
#pragma once

#include <cmath>

#include "core/host_device.hpp"
#include "lancer/camera.hpp"

namespace lancer {

// u = (2 film_x / W - 1) tan(fov / 2) (W / H) and v = (1 - 2 film_y / H) tan(fov / 2).
LANCER_HOST_DEVICE inline float film_u(const CameraFrame& camera, float film_x) {
    return (2.0f * film_x / static_cast<float>(camera.width) - 1.0f) * camera.tan_half_fov * camera.aspect;
}
LANCER_HOST_DEVICE inline float film_v(const CameraFrame& camera, float film_y) {
    return (1.0f - 2.0f * film_y / static_cast<float>(camera.height)) * camera.tan_half_fov;
}

// normalize(f + u x + v y), as d / sqrt(d.d).
LANCER_HOST_DEVICE inline Vec3f film_direction(const CameraFrame& camera, float u, float v) {
    const Vec3f d = camera.forward + u * camera.right + v * camera.up;
    return d / sqrtf(dot(d, d));
}

// The ray through film position (film_x, film_y): PinholeCamera::generate's contract.
LANCER_HOST_DEVICE inline Ray camera_ray(const CameraFrame& camera, float film_x, float film_y) {
    Ray ray;
    ray.origin = camera.eye;
    ray.direction = film_direction(camera, film_u(camera, film_x), film_v(camera, film_y));
    ray.tnear = 0.0f;
    ray.tfar = kInfinity;
    return ray;
}

}  // namespace lancer
