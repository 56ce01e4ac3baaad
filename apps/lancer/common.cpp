#include "common.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <charconv>

#include "lancer/io.hpp"

namespace lancer::cli {

LoadedScene load_timed(const std::filesystem::path& file) {
    Stopwatch watch;
    LoadedScene loaded{load_scene(file), 0.0};
    loaded.load_ms = watch.elapsed_ms();
    return loaded;
}

void AccelChoice::add_options(CLI::App& command) {
    std::string names;
    for (std::string_view known : accel_names())
        names += (names.empty() ? "" : ", ") + std::string(known);
    command.add_option("--accel", name, "Acceleration structure: " + names)->capture_default_str();
    command.add_flag("--watertight", watertight, "Watertight triangle test (Woop, Benthin & Wald 2013)");
    command.add_option("--set", settings, "Structure option KEY=VALUE, e.g. bvh.builder=sweep (repeatable)");
}

BuildOptions AccelChoice::build_options() const {
    BuildOptions options =
        lancer::build_options(watertight ? TriangleTest::Watertight : TriangleTest::MollerTrumbore);
    try {
        for (const std::string& setting : settings)
            set_build_option(options, setting);
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    }
    return options;
}

BuiltAccel build_timed(const AccelChoice& choice, const Geometry& geometry) {
    BuiltAccel built;
    const BuildOptions options = choice.build_options();
    try {
        built.accel = make_accel(choice.name);
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    }
    Stopwatch watch;
    built.accel->build(geometry, options);
    built.build_ms = watch.elapsed_ms();
    return built;
}

void intersect_parallel(const Accel& accel, std::span<const Ray> rays, std::span<Hit> hits, int threads) {
    // Chunks big enough to amortise the virtual call, small enough to balance two cores on uneven rays.
    constexpr std::size_t chunk = 4096;
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), chunk),
                          [&](const tbb::blocked_range<std::size_t>& range) {
                              accel.intersect(rays.subspan(range.begin(), range.size()),
                                              hits.subspan(range.begin(), range.size()));
                          });
    });
}

bool stderr_is_terminal() {
    return isatty(STDERR_FILENO) != 0;
}

std::pair<int, int> parse_size(const std::string& text) {
    const auto separator = text.find('x');
    int width = 0, height = 0;
    if (separator != std::string::npos) {
        const char* begin = text.data();
        const char* middle = begin + separator;
        const char* end = begin + text.size();
        auto [width_end, width_error] = std::from_chars(begin, middle, width);
        auto [height_end, height_error] = std::from_chars(middle + 1, end, height);
        if (width_error == std::errc{} && height_error == std::errc{} && width_end == middle &&
            height_end == end && width > 0 && height > 0 && width <= 32768 && height <= 32768) {
            return {width, height};
        }
    }
    throw InputError("--size: expected WIDTHxHEIGHT with both in [1, 32768], got '" + text + "'");
}

}  // namespace lancer::cli
