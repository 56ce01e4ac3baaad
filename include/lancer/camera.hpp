// Primary-ray generation for the pinhole camera (seed 004; shared/bench/VIEWS.md).
#pragma once

#include <span>
#include <vector>

#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer {

class PinholeCamera {
  public:
    explicit PinholeCamera(const Camera& camera);

    // The ray through film position (film_x, film_y) in pixels: x from 0 (left edge) to width, y from 0 (top
    // edge) to height; the centre of pixel (i, j) is (i + 0.5, j + 0.5). Unit direction, tnear 0, tfar inf:
    //   u = (2 film_x / W - 1) tan(fov / 2) (W / H),  v = (1 - 2 film_y / H) tan(fov / 2),
    //   direction = normalize(f + u x + v y).
    [[nodiscard]] Ray generate(float film_x, float film_y) const;
    // A packet's pixels: kBlockSide x kBlockSide.
    static constexpr int kBlockSide = 4;
    // The rays through the pixel centres of the block [x0, x0 + 4) x [y0, y0 + 4), row by row: generate's
    // rays, bit for bit, made 16 at a time in SIMD lanes.
    void block_rays(int x0, int y0, std::span<Ray, kBlockSide * kBlockSide> out) const;
    // The rays through the pixel centres of [x0, x1) x [y0, y1), row by row.
    [[nodiscard]] std::vector<Ray> pixel_centre_rays(int x0, int y0, int x1, int y1) const;
    [[nodiscard]] int width() const { return width_; }
    [[nodiscard]] int height() const { return height_; }

  private:
    // The two film coordinates u(film_x) and v(film_y) of the formula above, and the direction from them.
    [[nodiscard]] float film_u(float film_x) const;
    [[nodiscard]] float film_v(float film_y) const;
    [[nodiscard]] Vec3f direction(float u, float v) const;

    Vec3f eye_, forward_, right_, up_;
    float tan_half_fov_, aspect_;
    int width_, height_;
};

}  // namespace lancer
