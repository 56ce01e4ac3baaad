// Primary-ray generation for the pinhole camera (the "Lancer de rayon" slides; shared/bench/VIEWS.md).
#pragma once

#include <span>
#include <vector>

#include "lancer/packet.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer {

// A pinhole camera as it makes rays (VIEWS.md): the eye, the unit forward axis f = normalize(look_at - eye),
// the right axis x = normalize(cross(f, up)), the up axis y = cross(x, f), tan(fov / 2), W / H and the
// image's size. The CPU (PinholeCamera) and the GPU's frame kernels make their rays from it by one source.
struct CameraFrame {
    Vec3f eye, forward, right, up;
    float tan_half_fov = 0.0f, aspect = 1.0f;
    int width = 0, height = 0;
};

class PinholeCamera {
  public:
    explicit PinholeCamera(const Camera& camera);

    // The ray through film position (film_x, film_y) in pixels: x from 0 (left edge) to width, y from 0 (top
    // edge) to height; the centre of pixel (i, j) is (i + 0.5, j + 0.5). Unit direction, tnear 0, tfar inf:
    //   u = (2 film_x / W - 1) tan(fov / 2) (W / H),  v = (1 - 2 film_y / H) tan(fov / 2),
    //   direction = normalize(f + u x + v y).
    [[nodiscard]] Ray generate(float film_x, float film_y) const;
    // A packet's pixels: a tile of kTileSide x kTileSide, in blocks of kBlockSide x kBlockSide.
    static constexpr int kTileSide = 8;
    static constexpr int kBlockSide = 4;
    static_assert(kTileSide * kTileSide == RayPacket::kMaxSize);
    static constexpr int kBlockLanes = kBlockSide * kBlockSide;
    static constexpr int kBlocksPerTileRow = kTileSide / kBlockSide;
    // The corner of block `block` of a tile (blocks row by row), from the tile's corner.
    [[nodiscard]] static constexpr int block_column(int block) {
        return kBlockSide * (block % kBlocksPerTileRow);
    }
    [[nodiscard]] static constexpr int block_row(int block) {
        return kBlockSide * (block / kBlocksPerTileRow);
    }
    // The pixel of lane `lane` of tile_rays's packet, from the tile's corner: lane 16 b + 4 r + c is column
    // c and row r of block b, so that every 16 lanes from a multiple of 16 are a 4x4 block and every 8 a 4x2
    // one (the packets Embree's tutorials trace).
    [[nodiscard]] static constexpr int tile_column(int lane) {
        return block_column(lane / kBlockLanes) + lane % kBlockSide;
    }
    [[nodiscard]] static constexpr int tile_row(int lane) {
        return block_row(lane / kBlockLanes) + (lane / kBlockSide) % kBlockSide;
    }
    // The rays through the pixel centres of the tile [x0, x0 + 8) x [y0, y0 + 8), 64 lanes in that order:
    // generate's rays, bit for bit, made in SIMD lanes. A lane whose pixel lies outside the image gets a ray
    // of zero direction, which misses (is_valid).
    void tile_rays(int x0, int y0, RayPacket& out) const;
    // The rays through the pixel centres of [x0, x1) x [y0, y1), row by row.
    [[nodiscard]] std::vector<Ray> pixel_centre_rays(int x0, int y0, int x1, int y1) const;
    [[nodiscard]] int width() const { return frame_.width; }
    [[nodiscard]] int height() const { return frame_.height; }
    [[nodiscard]] const CameraFrame& frame() const { return frame_; }

  private:
    CameraFrame frame_;
};

}  // namespace lancer
