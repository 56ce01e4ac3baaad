// lancer nearest MESH --points POINTS --nearest NEAREST: the nearest surface point of each query point.
// POINTS: raw little-endian float32, 3 per point (x y z).
// NEAREST: 28 bytes per point: float32 x, y, z (the nearest point), float32 distance, int32 primitive (-1
// for an empty scene), float32 u, v (its barycentric coordinates on that triangle) = lancer::NearestPoint.
#include <fmt/core.h>

#include <bit>
#include <cmath>
#include <fstream>
#include <memory>
#include <vector>

#include "commands.hpp"
#include "common.hpp"
#include "lancer/parallel.hpp"
#include "lancer/queries.hpp"

namespace lancer::cli {
namespace {

static_assert(std::endian::native == std::endian::little && sizeof(NearestPoint) == 28,
              "POINTS and NEAREST files are little-endian and written by memcpy");

struct NearestOptions {
    std::string scene_file;
    std::string points_file;
    std::string nearest_file;
    int threads = 0;
};

std::vector<Vec3f> read_points(const std::string& path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw InputError(path + ": cannot open the points file");
    const auto bytes = static_cast<std::size_t>(in.tellg());
    if (bytes % sizeof(Vec3f) != 0)
        throw InputError(fmt::format("{}: {} bytes is not a whole number of 12-byte points (3 float32 each)",
                                     path, bytes));
    std::vector<Vec3f> points(bytes / sizeof(Vec3f));
    in.seekg(0);
    if (!in.read(reinterpret_cast<char*>(points.data()), static_cast<std::streamsize>(bytes)))
        throw InputError(path + ": read error");
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (!std::isfinite(points[i].x) || !std::isfinite(points[i].y) || !std::isfinite(points[i].z))
            throw InputError(fmt::format("{}: point {} has a NaN or infinite coordinate", path, i));
    }
    return points;
}

void run(const NearestOptions& options) {
    const LoadedScene loaded = load_timed(options.scene_file);
    const SceneGeometry geometry(loaded.scene);
    Stopwatch build_watch;
    const GeometryQueries queries(geometry.view(), TriangleTest::Watertight);
    const double build_ms = build_watch.elapsed_ms();
    const std::vector<Vec3f> points = read_points(options.points_file);
    Stopwatch watch;
    std::vector<NearestPoint> nearest(points.size());
    parallel_for(points.size(), 1024, options.threads, [&](std::size_t first, std::size_t last) {
        for (std::size_t i = first; i < last; ++i)
            nearest[i] = queries.nearest_point(points[i]);
    });
    const double query_ms = watch.elapsed_ms();
    std::ofstream out(options.nearest_file, std::ios::binary);
    out.write(reinterpret_cast<const char*>(nearest.data()),
              static_cast<std::streamsize>(nearest.size() * sizeof(NearestPoint)));
    if (!out) throw InputError(options.nearest_file + ": cannot write the nearest-point file");
    fmt::print(stderr, "nearest: {} points, BVH build {:.1f} ms, queries {:.1f} ms\n", points.size(),
               build_ms, query_ms);
}

}  // namespace

void add_nearest_command(CLI::App& app) {
    auto options = std::make_shared<NearestOptions>();
    CLI::App* command = app.add_subcommand(
        "nearest", "The nearest surface point of each of a binary batch of points (formats in README)");
    command->add_option("scene", options->scene_file, "Mesh or scene file")->required();
    command->add_option("--points", options->points_file, "Input: float32 x 3 per point")->required();
    command->add_option("--nearest", options->nearest_file, "Output: 28 bytes per point")->required();
    command->add_option("--threads", options->threads, "Threads (0 = all)")->check(CLI::NonNegativeNumber);
    add_memory_limit_option(*command);
    command->callback([options] { run(*options); });
}

}  // namespace lancer::cli
