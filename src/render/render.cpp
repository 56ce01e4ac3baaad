// Tiles of pixels over oneTBB threads. Each pixel's colour depends on its own rays alone, and the one
// image-wide quantity (the depth range) is taken after every tile is done, so the image is the same bit for
// bit whatever the thread count, the tile size and the order tiles finish in.
#include "lancer/render.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
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
    if (options.device != RenderDevice::Cpu)
        throw std::invalid_argument("render: the GPU renders a World (render(const World&, ...))");
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

// A frame's tiles: squares of options.tile_size numbered row-major, the last column and row clipped to the
// image. The renderer, the parts of a distributed frame and their assembly all index tiles through it.
class TileGrid {
  public:
    struct Rect {
        int x0, y0, x1, y1;  // pixels [x0, x1) x [y0, y1)
    };

    TileGrid(const Camera& camera, const RenderOptions& options)
        : width_(camera.width),
          height_(camera.height),
          // A tile larger than the image is the image; the clamp also keeps the tile arithmetic within an
          // int.
          tile_size_(std::min(options.tile_size, std::max(camera.width, camera.height))),
          columns_((width_ + tile_size_ - 1) / tile_size_),
          rows_((height_ + tile_size_ - 1) / tile_size_) {}

    [[nodiscard]] std::size_t count() const {
        return static_cast<std::size_t>(columns_) * static_cast<std::size_t>(rows_);
    }
    [[nodiscard]] Rect rect(std::size_t tile) const {
        const int x0 = static_cast<int>(tile % static_cast<std::size_t>(columns_)) * tile_size_;
        const int y0 = static_cast<int>(tile / static_cast<std::size_t>(columns_)) * tile_size_;
        return {x0, y0, std::min(x0 + tile_size_, width_), std::min(y0 + tile_size_, height_)};
    }
    // Calls visit(first pixel index, pixel count) for each row of `tile`, top down.
    template <class Visit>
    void for_each_row(std::size_t tile, Visit&& visit) const {
        const Rect r = rect(tile);
        for (int y = r.y0; y < r.y1; ++y)
            visit(static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) +
                      static_cast<std::size_t>(r.x0),
                  static_cast<std::size_t>(r.x1 - r.x0));
    }

  private:
    int width_, height_, tile_size_, columns_, rows_;
};

class TileRenderer {
  public:
    TileRenderer(const Scene& scene, const SceneIntersector& intersector, const PinholeCamera& camera,
                 const WhittedTracer& whitted, ShadingMode mode, const TileGrid& grid, Image& image,
                 std::vector<float>& depth, std::vector<TraversalCounters>& heat, AtomicRayCounts& rays)
        : scene_(scene),
          intersector_(intersector),
          camera_(camera),
          whitted_(whitted),
          mode_(mode),
          grid_(grid),
          image_(image),
          depth_(depth),
          heat_(heat),
          rays_(rays) {}

    // Tile `tile` (TileGrid): the Whitted ray tree of its samples, or the primary rays through its pixel
    // centres.
    void render(std::size_t tile) const {
        const auto [x0, y0, x1, y1] = grid_.rect(tile);
        if (mode_ == ShadingMode::Whitted) {
            rays_.add(whitted_.render_tile(x0, y0, x1, y1, image_));
            return;
        }

        if (mode_ == ShadingMode::Heatmap) {
            const std::vector<Ray> rays = camera_.pixel_centre_rays(x0, y0, x1, y1);
            std::vector<InstanceHit> hits(rays.size());
            trace_counting(rays, hits, x0, y0, x1);
            return;
        }
        // The camera rays straight into 8x8 packets, the structures' fastest path for them
        // (Accel::intersect_packet); the lanes of a packet that overhangs the tile are traced and dropped.
        RayPacket rays;
        std::array<InstanceHit, RayPacket::kMaxSize> hits;
        constexpr int kSide = PinholeCamera::kTileSide;
        for (int packet_y = y0; packet_y < y1; packet_y += kSide) {
            for (int packet_x = x0; packet_x < x1; packet_x += kSide) {
                camera_.tile_rays(packet_x, packet_y, rays);
                intersector_.intersect_packet(rays, hits);
                for (int lane = 0; lane < rays.size; ++lane) {
                    const int x = packet_x + PinholeCamera::tile_column(lane);
                    const int y = packet_y + PinholeCamera::tile_row(lane);
                    if (x < x1 && y < y1) shade(x, y, rays.ray(lane), hits[static_cast<std::size_t>(lane)]);
                }
            }
        }
        rays_.add({static_cast<std::size_t>(x1 - x0) * static_cast<std::size_t>(y1 - y0), 0, 0, 0});
    }

  private:
    // One ray at a time, so that each pixel gets its own count (a diagnostic mode: speed is not the point).
    void trace_counting(const std::vector<Ray>& rays, std::vector<InstanceHit>& hits, int x0, int y0,
                        int x1) const {
        const int width = x1 - x0;
        for (std::size_t k = 0; k < rays.size(); ++k) {
            const auto x = static_cast<std::size_t>(x0 + static_cast<int>(k) % width);
            const auto y = static_cast<std::size_t>(y0 + static_cast<int>(k) / width);
            intersector_.intersect({&rays[k], 1}, {&hits[k], 1},
                                   &heat_[y * static_cast<std::size_t>(image_.width) + x]);
        }
        rays_.add({rays.size(), 0, 0, 0});
    }

    void shade(int x, int y, const Ray& ray, const InstanceHit& hit) const {
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
    const TileGrid& grid_;
    Image& image_;
    std::vector<float>& depth_;             // hit distance per pixel, infinity on a miss; Depth mode only
    std::vector<TraversalCounters>& heat_;  // traversal counts per pixel; Heatmap mode only
    AtomicRayCounts& rays_;
};

// A frame's buffers and ray counts while its tiles are rendered: the image, and the per-pixel values of the
// modes whose image is made from the whole frame at the end (Depth, Heatmap).
struct FrameBuffers {
    Image image;
    std::vector<float> depth;
    std::vector<TraversalCounters> heat;
    AtomicRayCounts rays;

    FrameBuffers(const Camera& camera, ShadingMode mode) : image(camera.width, camera.height) {
        if (mode == ShadingMode::Depth) depth.resize(image.pixels.size());
        if (mode == ShadingMode::Heatmap) heat.resize(image.pixels.size());
    }
};

// Renders the tiles each call of `next_batch` returns (a std::vector<std::size_t>; empty: done), each
// batch over the threads of `options`.
template <class NextBatch>
void render_batches(const Scene& scene, const SceneIntersector& intersector, const Camera& camera,
                    const RenderOptions& options, FrameBuffers& frame, NextBatch&& next_batch) {
    const PinholeCamera pinhole(camera);
    const WhittedTracer whitted(scene, intersector, pinhole, options);
    const TileGrid grid(camera, options);
    const TileRenderer tiles(scene, intersector, pinhole, whitted, options.mode, grid, frame.image,
                             frame.depth, frame.heat, frame.rays);
    ProgressReporter progress("render", grid.count(), "tiles", options.progress);
    tbb::task_arena arena(options.threads == 0 ? tbb::task_arena::automatic : options.threads);
    for (std::vector<std::size_t> batch = next_batch(); !batch.empty(); batch = next_batch()) {
        for (const std::size_t tile : batch) {
            if (tile >= grid.count()) {
                throw std::invalid_argument("render: tile " + std::to_string(tile) + " of a frame of " +
                                            std::to_string(grid.count()));
            }
        }
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, batch.size(), 1),
                              [&](const tbb::blocked_range<std::size_t>& range) {
                                  for (std::size_t k = range.begin(); k != range.end(); ++k) {
                                      tiles.render(batch[k]);
                                      progress.advance();
                                  }
                              });
        });
    }
    progress.finish();
}

// The image-wide passes and the counts: the image render() returns.
Image finish_frame(FrameBuffers& frame, ShadingMode mode, RenderStats* stats) {
    if (mode == ShadingMode::Depth) depth_to_image(frame.depth, frame.image);
    if (mode == ShadingMode::Heatmap) {
        std::vector<std::uint32_t> nodes(frame.heat.size());
        for (std::size_t i = 0; i < frame.heat.size(); ++i)
            nodes[i] = static_cast<std::uint32_t>(frame.heat[i].nodes_visited);
        heat_to_image(nodes, frame.image);
    }
    if (stats != nullptr) {
        stats->primary_rays = frame.rays.primary;
        stats->shadow_rays = frame.rays.shadow;
        stats->reflection_rays = frame.rays.reflection;
        stats->refraction_rays = frame.rays.refraction;
        stats->counters = {};
        for (const TraversalCounters& pixel : frame.heat)
            stats->counters += pixel;
    }
    return std::move(frame.image);
}

}  // namespace

namespace {

// The whole frame through `intersector`.
Image render_frame(const Scene& scene, const SceneIntersector& intersector, const Camera& camera,
                   const RenderOptions& options, RenderStats* stats) {
    const auto start = std::chrono::steady_clock::now();
    check_options(camera, options);
    FrameBuffers frame(camera, options.mode);
    bool done = false;
    render_batches(scene, intersector, camera, options, frame, [&] {
        std::vector<std::size_t> all;
        if (!done) {
            all.resize(frame_tile_count(camera, options));
            for (std::size_t tile = 0; tile < all.size(); ++tile)
                all[tile] = tile;
            done = true;
        }
        return all;
    });
    Image image = finish_frame(frame, options.mode, stats);
    if (stats != nullptr)
        stats->trace_ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return image;
}

}  // namespace

Image render(const Scene& scene, const SceneGeometry& geometry, const Accel& accel, const Camera& camera,
             const RenderOptions& options, RenderStats* stats) {
    return render_frame(scene, SceneIntersector(scene, geometry, accel), camera, options, stats);
}

Image render(const InstancedWorld& world, const Camera& camera, const RenderOptions& options,
             RenderStats* stats) {
    if (options.device != RenderDevice::Cpu)
        throw std::invalid_argument(
            "render: an instanced scene renders on the CPU (the GPU kernels trace one "
            "structure's triangles)");
    return render_frame(world.scene(), SceneIntersector(world), camera, options, stats);
}

std::size_t frame_tile_count(const Camera& camera, const RenderOptions& options) {
    check_options(camera, options);
    return TileGrid(camera, options).count();
}

FramePart render_part(const Scene& scene, const SceneGeometry& geometry, const Accel& accel,
                      const Camera& camera, const RenderOptions& options,
                      const std::function<std::vector<std::size_t>()>& next_tiles) {
    check_options(camera, options);
    FrameBuffers frame(camera, options.mode);
    FramePart part;
    render_batches(scene, SceneIntersector(scene, geometry, accel), camera, options, frame, [&] {
        std::vector<std::size_t> batch = next_tiles();
        part.tiles.insert(part.tiles.end(), batch.begin(), batch.end());
        return batch;
    });
    const TileGrid grid(camera, options);
    std::size_t pixel_count = 0;
    for (const std::size_t tile : part.tiles) {
        const TileGrid::Rect r = grid.rect(tile);
        pixel_count += static_cast<std::size_t>(r.x1 - r.x0) * static_cast<std::size_t>(r.y1 - r.y0);
    }
    part.pixels.reserve(pixel_count);
    auto append = [](auto& to, const auto& from, std::size_t first, std::size_t count) {
        const auto begin = from.begin() + static_cast<std::ptrdiff_t>(first);
        to.insert(to.end(), begin, begin + static_cast<std::ptrdiff_t>(count));
    };
    for (const std::size_t tile : part.tiles) {
        grid.for_each_row(tile, [&](std::size_t first, std::size_t count) {
            append(part.pixels, frame.image.pixels, first, count);
            if (options.mode == ShadingMode::Depth) append(part.depth, frame.depth, first, count);
            if (options.mode == ShadingMode::Heatmap) append(part.heat, frame.heat, first, count);
        });
    }
    part.stats.primary_rays = frame.rays.primary;
    part.stats.shadow_rays = frame.rays.shadow;
    part.stats.reflection_rays = frame.rays.reflection;
    part.stats.refraction_rays = frame.rays.refraction;
    return part;
}

Image assemble_frame(const Camera& camera, const RenderOptions& options, std::span<const FramePart> parts,
                     RenderStats* stats) {
    check_options(camera, options);
    const TileGrid grid(camera, options);
    std::vector<std::uint8_t> seen(grid.count(), 0);
    FrameBuffers frame(camera, options.mode);
    for (const FramePart& part : parts) {
        if ((options.mode == ShadingMode::Depth && part.depth.size() != part.pixels.size()) ||
            (options.mode == ShadingMode::Heatmap && part.heat.size() != part.pixels.size()))
            throw std::invalid_argument("assemble_frame: a part's per-pixel values do not match its pixels");
        std::size_t value = 0;
        for (const std::size_t tile : part.tiles) {
            if (tile >= seen.size() || seen[tile] != 0) {
                throw std::invalid_argument("assemble_frame: tile " + std::to_string(tile) +
                                            (tile >= seen.size() ? " is not in the frame" : " comes twice"));
            }
            seen[tile] = 1;
            grid.for_each_row(tile, [&](std::size_t first, std::size_t count) {
                if (part.pixels.size() - value < count)
                    throw std::invalid_argument("assemble_frame: a part holds fewer pixels than its tiles");
                auto copy = [&](const auto& from, auto& to) {
                    std::copy_n(from.begin() + static_cast<std::ptrdiff_t>(value), count,
                                to.begin() + static_cast<std::ptrdiff_t>(first));
                };
                copy(part.pixels, frame.image.pixels);
                if (options.mode == ShadingMode::Depth) copy(part.depth, frame.depth);
                if (options.mode == ShadingMode::Heatmap) copy(part.heat, frame.heat);
                value += count;
            });
        }
        if (value != part.pixels.size())
            throw std::invalid_argument("assemble_frame: a part holds more pixels than its tiles");
        frame.rays.add({part.stats.primary_rays, part.stats.shadow_rays, part.stats.reflection_rays,
                        part.stats.refraction_rays});
    }
    const auto missing = std::find(seen.begin(), seen.end(), 0);
    if (missing != seen.end()) {
        throw std::invalid_argument("assemble_frame: tile " + std::to_string(missing - seen.begin()) +
                                    " was rendered by no part");
    }
    return finish_frame(frame, options.mode, stats);
}

}  // namespace lancer
