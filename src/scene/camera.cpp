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

// Inline: tile_rays vectorizes only with them inlined (only this file calls them).
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

void PinholeCamera::tile_rays(int x0, int y0, RayPacket& out) const {
    // u depends on the column only and v on the row only: 8 of each, not 64 (each a division).
    float u[kTileSide], v[kTileSide];
    for (int k = 0; k < kTileSide; ++k) {
        u[k] = film_u(static_cast<float>(x0 + k) + 0.5f);
        v[k] = film_v(static_cast<float>(y0 + k) + 0.5f);
    }
    // A block at a time, so that GCC vectorizes the loop across its 16 pixels; each lane's operations are
    // the scalar ones, so the rays are generate's bit for bit.
    for (int block = 0; block < RayPacket::kMaxSize / kBlockLanes; ++block) {
        const float* const block_u = u + block_column(block);
        const float* const block_v = v + block_row(block);
        float* const ox = out.origin[0] + block * kBlockLanes;
        float* const oy = out.origin[1] + block * kBlockLanes;
        float* const oz = out.origin[2] + block * kBlockLanes;
        float* const dx = out.direction[0] + block * kBlockLanes;
        float* const dy = out.direction[1] + block * kBlockLanes;
        float* const dz = out.direction[2] + block * kBlockLanes;
        float* const tnear = out.tnear + block * kBlockLanes;
        float* const tfar = out.tfar + block * kBlockLanes;
        for (int k = 0; k < kBlockLanes; ++k) {
            const Vec3f d = direction(block_u[k % kBlockSide], block_v[k / kBlockSide]);
            ox[k] = eye_.x, oy[k] = eye_.y, oz[k] = eye_.z;
            dx[k] = d.x, dy[k] = d.y, dz[k] = d.z;
            tnear[k] = 0.0f, tfar[k] = kInfinity;
        }
    }
    out.size = RayPacket::kMaxSize;
    if (x0 + kTileSide <= width_ && y0 + kTileSide <= height_) return;
    for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
        if (x0 + tile_column(lane) < width_ && y0 + tile_row(lane) < height_) continue;
        for (int axis = 0; axis < 3; ++axis)
            out.direction[axis][lane] = 0.0f;
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
