// Tiles of pixels over oneTBB threads. Each pixel's colour depends on its own rays alone, and the one
// image-wide quantity (the depth range) is taken after every tile is done, so the image is the same bit for
// bit whatever the thread count, the tile size and the order tiles finish in.
#include "lancer/render.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "lancer/camera.hpp"
#include "render/heatmap.hpp"
#include "render/progress.hpp"
#include "render/scene_intersector.hpp"
#include "render/whitted.hpp"

namespace lancer {
namespace {

// A tile holds tile_size^2 x samples camera samples at once; 4096 per pixel is far past visible noise.
constexpr int kMaxSamplesPerPixel = 4096;

void check_options(const Camera& camera, const RenderOptions& options) {
    if (camera.width <= 0 || camera.height <= 0) {
        throw std::invalid_argument("render: image size " + std::to_string(camera.width) + "x" +
                                    std::to_string(camera.height) + " is not positive");
    }
    if (options.tile_size <= 0) {
        throw std::invalid_argument("render: tile size " + std::to_string(options.tile_size) +
                                    " is not positive");
    }
    if (options.threads < 0) {
        throw std::invalid_argument("render: thread count " + std::to_string(options.threads) +
                                    " is negative (0 means all hardware threads)");
    }
    if (options.samples_per_pixel <= 0 || options.samples_per_pixel > kMaxSamplesPerPixel) {
        throw std::invalid_argument("render: samples per pixel " + std::to_string(options.samples_per_pixel) +
                                    " is not in [1, " + std::to_string(kMaxSamplesPerPixel) + "]");
    }
    if (options.max_depth <= 0) {
        throw std::invalid_argument("render: maximum depth " + std::to_string(options.max_depth) +
                                    " is not positive (the eye ray is depth 1)");
    }
    if (!(options.min_weight >= 0.0f)) {
        throw std::invalid_argument("render: minimum weight " + std::to_string(options.min_weight) +
                                    " is negative or NaN");
    }
}

// Rays a tile traced, added up over the threads.
struct AtomicRayCounts {
    std::atomic<std::uint64_t> primary{0}, shadow{0}, reflection{0}, refraction{0};

    void add(const RayCounts& counts) {
        primary.fetch_add(counts.primary, std::memory_order_relaxed);
        shadow.fetch_add(counts.shadow, std::memory_order_relaxed);
        reflection.fetch_add(counts.reflection, std::memory_order_relaxed);
        refraction.fetch_add(counts.refraction, std::memory_order_relaxed);
    }
};

// A headlight at the eye: the facet's cosine with the view, whichever side is seen (the paper's Figure 5).
Vec3f flat_color(const SurfacePoint& surface, const Ray& ray) {
    return surface.color * std::fabs(dot(surface.geometric_normal, normalize(ray.direction)));
}

// The side the ray arrives on is decided by the geometric normal and the shading normal follows it: near a
// silhouette an interpolated normal can point away from the viewer although its facet faces him, and
// flipping it alone would paint the back of the surface there.
Vec3f normal_color(const SurfacePoint& surface, const Ray& ray) {
    const bool back_side = dot(surface.geometric_normal, ray.direction) > 0.0f;
    const Vec3f normal = back_side ? -surface.shading_normal : surface.shading_normal;
    return normal * 0.5f + Vec3f(0.5f);
}

// White at the nearest hit of the image, black at the farthest and on misses.
void depth_to_image(const std::vector<float>& depth, Image& image) {
    float t_min = kInfinity, t_max = -kInfinity;
    for (float t : depth) {
        if (t == kInfinity) continue;
        t_min = std::min(t_min, t);
        t_max = std::max(t_max, t);
    }
    const float range = t_max - t_min;
    for (std::size_t i = 0; i < depth.size(); ++i) {
        if (depth[i] == kInfinity) {
            image.pixels[i] = Vec3f(0.0f);
        } else {
            // Every hit at one distance: all of them are the nearest.
            image.pixels[i] = Vec3f(range > 0.0f ? 1.0f - (depth[i] - t_min) / range : 1.0f);
        }
    }
}

class TileRenderer {
  public:
    TileRenderer(const Scene& scene, const SceneIntersector& intersector, const PinholeCamera& camera,
                 const WhittedTracer& whitted, ShadingMode mode, int tile_size, Image& image,
                 std::vector<float>& depth, std::vector<TraversalCounters>& heat, AtomicRayCounts& rays)
        : scene_(scene),
          intersector_(intersector),
          camera_(camera),
          whitted_(whitted),
          mode_(mode),
          tile_size_(tile_size),
          tile_columns_((image.width + tile_size - 1) / tile_size),
          tile_rows_((image.height + tile_size - 1) / tile_size),
          image_(image),
          depth_(depth),
          heat_(heat),
          rays_(rays) {}

    [[nodiscard]] std::size_t tile_count() const {
        return static_cast<std::size_t>(tile_columns_) * static_cast<std::size_t>(tile_rows_);
    }

    // Tile `tile` (row-major over the tile grid): the Whitted ray tree of its samples, or the primary rays
    // through its pixel centres.
    void render(std::size_t tile) const {
        const int x0 = static_cast<int>(tile % static_cast<std::size_t>(tile_columns_)) * tile_size_;
        const int y0 = static_cast<int>(tile / static_cast<std::size_t>(tile_columns_)) * tile_size_;
        const int x1 = std::min(x0 + tile_size_, image_.width);
        const int y1 = std::min(y0 + tile_size_, image_.height);
        if (mode_ == ShadingMode::Whitted) {
            rays_.add(whitted_.render_tile(x0, y0, x1, y1, image_));
            return;
        }

        if (mode_ == ShadingMode::Heatmap) {
            const std::vector<Ray> rays = camera_.pixel_centre_rays(x0, y0, x1, y1);
            std::vector<Hit> hits(rays.size());
            trace_counting(rays, hits, x0, y0, x1);
            return;
        }
        // The camera rays straight into 8x8 packets, the structures' fastest path for them
        // (Accel::intersect_packet); the lanes of a packet that overhangs the tile are traced and dropped.
        RayPacket rays;
        HitPacket hits;
        constexpr int kSide = PinholeCamera::kTileSide;
        for (int packet_y = y0; packet_y < y1; packet_y += kSide) {
            for (int packet_x = x0; packet_x < x1; packet_x += kSide) {
                camera_.tile_rays(packet_x, packet_y, rays);
                intersector_.intersect_packet(rays, hits);
                for (int lane = 0; lane < rays.size; ++lane) {
                    const int x = packet_x + PinholeCamera::tile_column(lane);
                    const int y = packet_y + PinholeCamera::tile_row(lane);
                    if (x < x1 && y < y1) shade(x, y, rays.ray(lane), hits.hit(lane));
                }
            }
        }
        rays_.add({static_cast<std::size_t>(x1 - x0) * static_cast<std::size_t>(y1 - y0), 0, 0, 0});
    }

  private:
    // One ray at a time, so that each pixel gets its own count (a diagnostic mode: speed is not the point).
    void trace_counting(const std::vector<Ray>& rays, std::vector<Hit>& hits, int x0, int y0, int x1) const {
        const int width = x1 - x0;
        for (std::size_t k = 0; k < rays.size(); ++k) {
            const auto x = static_cast<std::size_t>(x0 + static_cast<int>(k) % width);
            const auto y = static_cast<std::size_t>(y0 + static_cast<int>(k) / width);
            intersector_.intersect({&rays[k], 1}, {&hits[k], 1},
                                   &heat_[y * static_cast<std::size_t>(image_.width) + x]);
        }
        rays_.add({rays.size(), 0, 0, 0});
    }

    void shade(int x, int y, const Ray& ray, const Hit& hit) const {
        if (mode_ == ShadingMode::Depth) {
            depth_[static_cast<std::size_t>(y) * static_cast<std::size_t>(image_.width) + x] =
                hit.hit() ? hit.t : kInfinity;
            return;
        }
        if (!hit.hit()) {
            image_.at(x, y) = scene_.background;
            return;
        }
        const SurfacePoint surface = intersector_.surface(ray, hit);
        image_.at(x, y) = mode_ == ShadingMode::Flat ? flat_color(surface, ray) : normal_color(surface, ray);
    }

    const Scene& scene_;
    const SceneIntersector& intersector_;
    const PinholeCamera& camera_;
    const WhittedTracer& whitted_;
    ShadingMode mode_;
    int tile_size_;
    int tile_columns_;
    int tile_rows_;
    Image& image_;
    std::vector<float>& depth_;             // hit distance per pixel, infinity on a miss; Depth mode only
    std::vector<TraversalCounters>& heat_;  // traversal counts per pixel; Heatmap mode only
    AtomicRayCounts& rays_;
};

}  // namespace

Image render(const Scene& scene, const SceneGeometry& geometry, const Accel& accel, const Camera& camera,
             const RenderOptions& options, RenderStats* stats) {
    const auto start = std::chrono::steady_clock::now();
    check_options(camera, options);
    const SceneIntersector intersector(scene, geometry, accel);
    const PinholeCamera pinhole(camera);
    const WhittedTracer whitted(scene, intersector, pinhole, options);

    Image image(camera.width, camera.height);
    std::vector<float> depth;
    if (options.mode == ShadingMode::Depth) depth.resize(image.pixels.size());
    std::vector<TraversalCounters> heat;
    if (options.mode == ShadingMode::Heatmap) heat.resize(image.pixels.size());
    // A tile larger than the image is the image; the clamp also keeps the tile arithmetic within an int.
    const int tile_size = std::min(options.tile_size, std::max(image.width, image.height));
    AtomicRayCounts rays;
    const TileRenderer tiles(scene, intersector, pinhole, whitted, options.mode, tile_size, image, depth,
                             heat, rays);

    ProgressReporter progress("render", tiles.tile_count(), "tiles", options.progress);
    tbb::task_arena arena(options.threads == 0 ? tbb::task_arena::automatic : options.threads);
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tiles.tile_count(), 1),
                          [&](const tbb::blocked_range<std::size_t>& range) {
                              for (std::size_t tile = range.begin(); tile != range.end(); ++tile) {
                                  tiles.render(tile);
                                  progress.advance();
                              }
                          });
    });
    progress.finish();
    if (options.mode == ShadingMode::Depth) depth_to_image(depth, image);
    if (options.mode == ShadingMode::Heatmap) {
        std::vector<std::uint32_t> nodes(heat.size());
        for (std::size_t i = 0; i < heat.size(); ++i)
            nodes[i] = static_cast<std::uint32_t>(heat[i].nodes_visited);
        heat_to_image(nodes, image);
    }

    if (stats != nullptr) {
        stats->primary_rays = rays.primary;
        stats->shadow_rays = rays.shadow;
        stats->reflection_rays = rays.reflection;
        stats->refraction_rays = rays.refraction;
        for (const TraversalCounters& pixel : heat)
            stats->counters += pixel;
        stats->trace_ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    }
    return image;
}

}  // namespace lancer
