#include "lancer/camera.hpp"

#include <cmath>
#include <numbers>

#include "core/camera_ray.hpp"

namespace lancer {

PinholeCamera::PinholeCamera(const Camera& camera) {
    frame_.eye = camera.eye;
    frame_.tan_half_fov = std::tan(camera.vertical_fov_degrees * std::numbers::pi_v<float> / 360.0f);
    frame_.aspect = static_cast<float>(camera.width) / static_cast<float>(camera.height);
    frame_.width = camera.width;
    frame_.height = camera.height;
    // VIEWS.md: f = normalize(c - eye), x = normalize(cross(f, up)), y = cross(x, f).
    frame_.forward = normalize(camera.look_at - camera.eye);
    frame_.right = normalize(cross(frame_.forward, camera.up));
    frame_.up = cross(frame_.right, frame_.forward);
}

Ray PinholeCamera::generate(float film_x, float film_y) const {
    return camera_ray(frame_, film_x, film_y);
}

void PinholeCamera::tile_rays(int x0, int y0, RayPacket& out) const {
    // u depends on the column only and v on the row only: 8 of each, not 64 (each a division).
    float u[kTileSide], v[kTileSide];
    for (int k = 0; k < kTileSide; ++k) {
        u[k] = film_u(frame_, static_cast<float>(x0 + k) + 0.5f);
        v[k] = film_v(frame_, static_cast<float>(y0 + k) + 0.5f);
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
            const Vec3f d = film_direction(frame_, block_u[k % kBlockSide], block_v[k / kBlockSide]);
            ox[k] = frame_.eye.x, oy[k] = frame_.eye.y, oz[k] = frame_.eye.z;
            dx[k] = d.x, dy[k] = d.y, dz[k] = d.z;
            tnear[k] = 0.0f, tfar[k] = kInfinity;
        }
    }
    out.size = RayPacket::kMaxSize;
    if (x0 + kTileSide <= frame_.width && y0 + kTileSide <= frame_.height) return;
    for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
        if (x0 + tile_column(lane) < frame_.width && y0 + tile_row(lane) < frame_.height) continue;
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
