// lancer rays MESH --rays RAYS --hits HITS: batch closest-hit queries for tools and tests.
// RAYS: raw little-endian float32, 8 per ray (ox oy oz dx dy dz tnear tfar) = lancer::Ray.
// HITS: 16 bytes per ray (float32 t, int32 primitive, float32 u, float32 v) = lancer::Hit.
#include <fmt/core.h>

#include <bit>
#include <fstream>
#include <memory>
#include <optional>
#include <vector>

#include "commands.hpp"
#include "common.hpp"
#include "cuda_device.hpp"
#include "distributed.hpp"

namespace lancer::cli {
namespace {

static_assert(std::endian::native == std::endian::little,
              "RAYS and HITS files are little-endian and read by memcpy: add byte swapping for this target");

struct RaysOptions {
    std::string scene_file;
    std::string rays_file;
    std::string hits_file;
    AccelChoice accel;
    DeviceChoice device;
    int threads = 0;
};

std::vector<Ray> read_rays(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw InputError(path + ": cannot open the rays file");
    const auto bytes = static_cast<std::size_t>(in.tellg());
    if (bytes % sizeof(Ray) != 0) {
        throw InputError(
            fmt::format("{}: {} bytes is not a whole number of 32-byte rays (8 float32 each)", path, bytes));
    }
    std::vector<Ray> rays(bytes / sizeof(Ray));
    in.seekg(0);
    if (!in.read(reinterpret_cast<char*>(rays.data()), static_cast<std::streamsize>(bytes))) {
        throw InputError(path + ": read error");
    }
    return rays;
}

void write_hits(const std::string& path, const std::vector<Hit>& hits) {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(hits.data()),
              static_cast<std::streamsize>(hits.size() * sizeof(Hit)));
    if (!out) throw InputError(path + ": cannot write the hits file");
}

void run(const RaysOptions& options) {
    options.device.require_available();
    const Job& job = Job::get();
    if (job.distributed() && options.device.cuda())
        throw InputError("under mpirun, lancer rays runs on the CPU alone: leave out --device");
    // Every rank loads the scene and builds its structure; rank 0 reads the rays and hands each rank its
    // slice (docs/distributed.md).
    std::optional<PreparedScene> prepared;
    job.on_every_rank("loading the scene",
                      [&] { prepared = prepare_scene(options.scene_file, options.accel); });
    const World& world = prepared->world;
    std::vector<Ray> rays;
    job.on_every_rank("reading the rays", [&] {
        if (job.is_root()) rays = read_rays(options.rays_file);
    });

    std::vector<Hit> hits;
    Stopwatch watch;
    if (options.device.cuda()) {
        hits = make_cuda_tracer(options.device, world.options().triangle_test, world.accel(),
                                world.geometry().view())
                   ->trace(rays)
                   .hits;
    } else {
        hits = job.intersect(world.accel(), rays, options.threads);
    }
    const double trace_ms = watch.elapsed_ms();
    if (!job.is_root()) return;  // rank 0 writes the hits and the summary
    write_hits(options.hits_file, hits);

    std::size_t hit_count = 0;
    for (const Hit& hit : hits)
        hit_count += hit.hit() ? 1 : 0;
    fmt::print(stderr, "rays: {} rays, {} hits, accel {} (build {:.1f} ms), trace {:.1f} ms\n", rays.size(),
               hit_count, world.accel().name(), prepared->build_ms, trace_ms);
}

}  // namespace

void add_rays_command(CLI::App& app) {
    auto options = std::make_shared<RaysOptions>();
    CLI::App* command =
        app.add_subcommand("rays", "Closest hits of a binary batch of rays (formats in README)");
    command->add_option("scene", options->scene_file, "Mesh or scene file, or a .plo octree (lancer convert)")
        ->required();
    command->add_option("--rays", options->rays_file, "Input: float32 x 8 per ray")->required();
    command->add_option("--hits", options->hits_file, "Output: 16 bytes per ray")->required();
    options->accel.add_options(*command);
    options->device.add_options(*command);
    command->add_option("--threads", options->threads, "Threads (0 = all)")->check(CLI::NonNegativeNumber);
    command->callback([options] { run(*options); });
}

}  // namespace lancer::cli
