// The renderer: tiles of pixels over oneTBB threads, one closest-hit batch per tile (per ray-tree level in
// Whitted mode).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/cuda.hpp"
#include "lancer/scene.hpp"
#include "lancer/world.hpp"

namespace lancer {

enum class ShadingMode {
    Whitted,  // Ferreira & Mendoza 2011, 4.3: ambient, shadowed Phong point lights, mirror and refracted rays
    Flat,     // the paper's Figure 5 look: material colour times |cos| between geometric normal and ray
    Normal,   // shading normal mapped from [-1, 1] to [0, 1]
    Depth,    // distance along the ray, near = white, far = black, misses black
    Heatmap,  // traversal cost: nodes or cells visited per primary ray, black to white through a
              // perceptual ramp, with a legend (0 .. image maximum) in the bottom-left corner
};

// Where render(const World&, ...) traces the primary rays: the CPU, or an NVIDIA GPU through CudaTracer
// (lancer/cuda.hpp), whose kernels trace the structure's triangles alone and so render ShadingMode::Flat
// and Heatmap of scenes without infinite planes.
enum class RenderDevice { Cpu, Cuda };

struct RenderOptions {
    ShadingMode mode = ShadingMode::Whitted;
    RenderDevice device = RenderDevice::Cpu;
    std::optional<CudaKernel> cuda_kernel;  // RenderDevice::Cuda: default_cuda_kernel(the structure) if empty
    int threads = 0;                        // 0: all hardware threads
    int tile_size = 16;                     // pixels per tile side
    bool progress = false;  // a progress line on stderr (the CLI turns it on when stderr is a terminal)
    // Whitted mode (docs/whitted.md):
    int samples_per_pixel = 1;  // stratified over the pixel (a Hammersley set); 1 = the pixel centre
    int max_depth = 5;          // ray-tree depth, the eye ray being 1 (Ferreira & Mendoza 2011, 5; SPD: 5)
    // A reflected or refracted ray whose weight (product of ks and kt from the eye) is not above this is not
    // traced. 0 traces every ray with a positive weight, as the SPD asks.
    float min_weight = 1.0f / 512.0f;
    bool fresnel = false;  // split kt between reflection and refraction by Fresnel's dielectric reflectance
};

// Linear RGB, row-major, top row first.
struct Image {
    int width = 0;
    int height = 0;
    std::vector<Vec3f> pixels;

    Image() = default;
    Image(int w, int h)
        : width(w), height(h), pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h)) {}
    [[nodiscard]] Vec3f& at(int x, int y) { return pixels[static_cast<std::size_t>(y) * width + x]; }
    [[nodiscard]] const Vec3f& at(int x, int y) const {
        return pixels[static_cast<std::size_t>(y) * width + x];
    }
};

struct RenderStats {
    double trace_ms = 0.0;
    std::uint64_t primary_rays = 0;
    std::uint64_t shadow_rays = 0;      // Whitted mode: one per light a surface faces
    std::uint64_t reflection_rays = 0;  // Whitted mode: mirror rays, total internal reflections included
    std::uint64_t refraction_rays = 0;  // Whitted mode
    TraversalCounters counters;         // Heatmap mode only: summed over the image

    [[nodiscard]] std::uint64_t total_rays() const {
        return primary_rays + shadow_rays + reflection_rays + refraction_rays;
    }
};

// Renders `camera`'s view. `accel` must have been built on `geometry`, which was made from `scene`;
// the scene's infinite planes are tested beside the structure. Throws std::invalid_argument for a
// non-positive image or tile size, a negative thread count, a non-positive sample count or depth, a
// negative or NaN minimum weight, or a scene whose primitives name missing materials.
[[nodiscard]] Image render(const Scene& scene, const SceneGeometry& geometry, const Accel& accel,
                           const Camera& camera, const RenderOptions& options, RenderStats* stats = nullptr);

// render() of a World, on options.device. On the GPU, stats->trace_ms is the kernel's time. Throws as
// render() does, std::invalid_argument for a mode or scene the GPU does not render or a kernel that does not
// trace the structure, and CudaError when no GPU can be used.
[[nodiscard]] Image render(const World& world, const Camera& camera, const RenderOptions& options,
                           RenderStats* stats = nullptr);

// render() of an InstancedWorld on the CPU, in every mode: the same image as its scene flattened would give,
// up to the transformed rays' rounding. Throws as render() does, and std::invalid_argument for
// RenderDevice::Cuda (the GPU kernels trace one structure's triangles).
[[nodiscard]] Image render(const InstancedWorld& world, const Camera& camera, const RenderOptions& options,
                           RenderStats* stats = nullptr);

// A frame rendered in parts, by several processes (`mpirun lancer render`: docs/distributed.md). The
// frame's tiles are the squares of options.tile_size (clipped to the image) numbered row-major; every part
// renders the tiles it is handed, and assemble_frame() makes from parts that hold each tile once the image
// render() makes, bit for bit.
[[nodiscard]] std::size_t frame_tile_count(const Camera& camera, const RenderOptions& options);

// What a part rendered: its tiles in order, and for each tile its pixels row by row (the image's colour,
// and the per-pixel value that Depth and Heatmap modes turn into the image once the whole frame is there).
struct FramePart {
    std::vector<std::size_t> tiles;
    std::vector<Vec3f> pixels;
    std::vector<float> depth;             // Depth mode: the hit distance, infinity on a miss
    std::vector<TraversalCounters> heat;  // Heatmap mode: the primary ray's counts
    RenderStats stats;                    // the rays it traced (trace_ms left to the caller)
};

// Renders the tiles `next_tiles` returns, call after call, until it returns none; each batch runs over
// options.threads threads. Throws as render() does, and std::invalid_argument for a tile not in the frame.
[[nodiscard]] FramePart render_part(const Scene& scene, const SceneGeometry& geometry, const Accel& accel,
                                    const Camera& camera, const RenderOptions& options,
                                    const std::function<std::vector<std::size_t>()>& next_tiles);

// The image of the parts' tiles, with the rays they traced in `stats` (not trace_ms). Throws
// std::invalid_argument when a tile is missing or comes twice, or a part's pixels do not match its tiles.
[[nodiscard]] Image assemble_frame(const Camera& camera, const RenderOptions& options,
                                   std::span<const FramePart> parts, RenderStats* stats = nullptr);

// 8-bit sRGB PNG (libpng). Throws std::runtime_error with the path and the reason on failure.
void write_png(const Image& image, const std::filesystem::path& file);

// OpenEXR, linear half-float RGB. Throws std::runtime_error with the path and the reason on failure.
void write_exr(const Image& image, const std::filesystem::path& file);

}  // namespace lancer
