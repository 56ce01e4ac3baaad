// lancer bench: the throughput of every structure on the views of shared/bench/VIEWS.md, Embree beside
// lancer in the same process on the same rays and threads. Every structure's answers are checked against
// the first structure's before it is timed, ray by ray; a disagreement fails the bench (exit code 1). The
// canonical (primary) view's rays go to the structures in 8x8 pixel tiles, tiles in scanline order
// (trace_frame); the secondary views' (diffuse, shadow) are made once per mesh and traced from an array in
// memory, 4096 consecutive rays a task (intersect_parallel, occluded_parallel): Embree's rows then call
// rtcIntersectN or rtcOccludedN on consecutive rays without the COHERENT flag.
#include <fmt/core.h>
#include <fmt/os.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>

#include "commands.hpp"
#include "common.hpp"
#include "cuda_device.hpp"
#include "distributed.hpp"
#include "lancer/agreement.hpp"
#include "lancer/camera.hpp"
#include "lancer/denormals.hpp"
#include "lancer/generate.hpp"
#include "lancer/isa.hpp"
#include "lancer/views.hpp"

namespace lancer::cli {
namespace {

namespace fs = std::filesystem;

struct BenchOptions {
    std::vector<std::string> meshes;
    std::string accel_list = "all";
    std::string thread_list = "1,2";
    std::string view_list = "primary";
    int size = 1024;
    int frames = 5;
    bool moller_trumbore = false;
    std::vector<std::string> settings;
    std::string json_file;
    std::string svg_file;
    bool mpi = false;
    DeviceChoice device;
};

// The canonical view's camera rays, or one of the secondary sets made from its hits.
enum class BenchView { Primary, Diffuse, Shadow };

std::string_view view_name(BenchView view) {
    switch (view) {
        case BenchView::Primary:
            return "primary";
        case BenchView::Diffuse:
            return secondary_view_name(SecondaryView::Diffuse);
        case BenchView::Shadow:
            return secondary_view_name(SecondaryView::Shadow);
    }
    return "";
}

struct Record {
    std::string mesh;
    BenchView view = BenchView::Primary;
    std::size_t triangles = 0;
    std::string accel;
    int threads = 0;
    double build_ms = 0.0;
    std::size_t memory_bytes = 0;
    std::size_t geometry_bytes = 0;
    double mrays_median = 0.0, mrays_min = 0.0, mrays_max = 0.0;
    double hit_fraction = 0.0;
    double nodes_per_ray = 0.0, prims_per_ray = 0.0;
    bool counted = false;        // false for structures that expose no traversal counts (Embree)
    std::size_t mismatches = 0;  // rays answered otherwise than by the first structure (Embree rows only)
};

std::vector<BenchView> parse_views(const std::string& text) {
    std::vector<BenchView> views;
    std::stringstream stream(text);
    std::string item;
    while (std::getline(stream, item, ',')) {
        const auto known = {BenchView::Primary, BenchView::Diffuse, BenchView::Shadow};
        const auto view = std::find_if(known.begin(), known.end(),
                                       [&](BenchView candidate) { return view_name(candidate) == item; });
        if (view == known.end())
            throw InputError(
                fmt::format("--view: expected a comma-separated list of primary, diffuse and "
                            "shadow, got '{}'",
                            text));
        if (std::find(views.begin(), views.end(), *view) == views.end()) views.push_back(*view);
    }
    if (views.empty()) throw InputError("--view: empty list");
    return views;
}

std::string per_ray(double value, bool counted) {
    return counted ? fmt::format("{:.2f}", value) : "n/a";
}

struct BenchMesh {
    std::string name;
    Scene scene;
};

std::vector<int> parse_int_list(const std::string& text, const char* what) {
    std::vector<int> values;
    std::stringstream stream(text);
    std::string item;
    while (std::getline(stream, item, ',')) {
        try {
            std::size_t used = 0;
            const int value = std::stoi(item, &used);
            if (used != item.size() || value < 1 || value > 1024) throw std::invalid_argument(item);
            values.push_back(value);
        } catch (const std::exception&) {
            throw InputError(fmt::format(
                "{}: expected a comma-separated list of integers in [1, 1024], got '{}'", what, text));
        }
    }
    if (values.empty()) throw InputError(fmt::format("{}: empty list", what));
    return values;
}

std::vector<std::string> parse_accels(const std::string& text) {
    std::vector<std::string> names;
    if (text == "all") {
        for (std::string_view name : accel_names()) {
            if (name != "brute") names.emplace_back(name);  // brute force at 1M rays x 1M triangles: hours
        }
        return names;
    }
    std::stringstream stream(text);
    std::string item;
    while (std::getline(stream, item, ','))
        names.push_back(item);
    return names;
}

// The Stanford meshes when shared/data is there, else torus knots of the same sizes (VIEWS.md).
std::vector<BenchMesh> load_meshes(const BenchOptions& options) {
    std::vector<BenchMesh> meshes;
    std::vector<std::string> files = options.meshes;
    if (files.empty()) {
        const fs::path shared = fs::path(LANCER_SHARED_DIR) / "data" / "meshes";
        for (const char* name : {"bunny.obj", "armadillo.off", "dragon.ply"}) {
            if (fs::exists(shared / name)) files.push_back((shared / name).string());
        }
    }
    for (const std::string& file : files)
        meshes.push_back({fs::path(file).filename().string(), load_timed(file).scene});
    if (meshes.empty()) {
        for (const auto& [name, segments] :
             {std::pair{"knot-70k", 1750}, {"knot-350k", 8750}, {"knot-870k", 21800}}) {
            BenchMesh mesh{name, {}};
            mesh.scene.meshes.push_back(make_torus_knot(segments, 20));
            mesh.scene.materials.emplace_back();
            meshes.push_back(std::move(mesh));
        }
    }
    return meshes;
}

// Rays are generated in square tiles of kTileSide x kTileSide pixels, one RayPacket each, and the tiles go in
// scanline order. PinholeCamera::tile_rays writes a tile's rays straight into the packet, every 16 lanes a
// 4x4 pixel block and every 8 a 4x2 one: the packets Embree's tutorials trace (embree8, embree16), and the
// packet structures' (bvh8_packet). Every structure gets the same packets; hits are stored and compared at
// their pixel.
constexpr int kTileSide = PinholeCamera::kTileSide;

int tile_rows(const PinholeCamera& camera) {
    return (camera.height() + kTileSide - 1) / kTileSide;
}

// Calls visit(x0, y0) for the corner of every tile of the tile rows [first_row, last_row), in scanline order.
template <class Visit>
void for_each_tile(const PinholeCamera& camera, int first_row, int last_row, Visit&& visit) {
    for (int tile_row = first_row; tile_row < last_row; ++tile_row) {
        for (int x0 = 0; x0 < camera.width(); x0 += kTileSide)
            visit(x0, tile_row * kTileSide);
    }
}

// Calls visit(lane, pixel) for every lane of the tile at (x0, y0) whose pixel lies in the image, pixel
// being its index in row-major order.
template <class Visit>
void for_each_tile_pixel(const PinholeCamera& camera, int x0, int y0, Visit&& visit) {
    const auto width = static_cast<std::size_t>(camera.width());
    for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
        const int i = x0 + PinholeCamera::tile_column(lane), j = y0 + PinholeCamera::tile_row(lane);
        if (i < camera.width() && j < camera.height())
            visit(lane, static_cast<std::size_t>(j) * width + static_cast<std::size_t>(i));
    }
}

// Each lane's hit at its pixel. A tile inside the image goes a block row at a time: 4 lanes, 4 pixels in a
// row of the image (HitPacket::copy_four).
void store_tile_hits(const PinholeCamera& camera, int x0, int y0, const HitPacket& tile_hits,
                     std::vector<Hit>& hits) {
    if (x0 + kTileSide > camera.width() || y0 + kTileSide > camera.height()) {
        for_each_tile_pixel(camera, x0, y0,
                            [&](int lane, std::size_t pixel) { hits[pixel] = tile_hits.hit(lane); });
        return;
    }
    const auto width = static_cast<std::size_t>(camera.width());
    for (int lane = 0; lane < RayPacket::kMaxSize; lane += PinholeCamera::kBlockSide) {
        Hit* const row = hits.data() + static_cast<std::size_t>(y0 + PinholeCamera::tile_row(lane)) * width +
                         static_cast<std::size_t>(x0 + PinholeCamera::tile_column(lane));
        tile_hits.copy_four(lane, row);
    }
}

// The tiles of the tile rows [first_row, last_row): each tile's rays generated into a packet, traced
// (Accel::intersect_packet), and each closest hit stored at its pixel of `hits`.
void trace_tiles(const Accel& accel, const PinholeCamera& camera, int first_row, int last_row,
                 std::vector<Hit>& hits, TraversalCounters* counters = nullptr) {
    RayPacket rays;
    HitPacket tile_hits;
    const auto width = static_cast<std::size_t>(camera.width());
    for_each_tile(camera, first_row, last_row, [&](int x0, int y0) {
        camera.tile_rays(x0, y0, rays);
        // The tile's pixels asked for, for writing, before the trace: the 64 hits are stored at once after
        // it, and the lines of a cold 16 MB image fetched then stalled the stores (Embree's tutorials store
        // each packet's hits as they come, which overlaps those fetches with the trace). Written here, not in
        // a function of its own: GCC deems a function of prefetches alone pure and drops its calls.
        // A tile row's 128 bytes may straddle three lines: every fourth pixel and the last are asked for.
        const int columns = std::min(kTileSide, camera.width() - x0);
        for (int row = 0; row < std::min(kTileSide, camera.height() - y0); ++row) {
            const Hit* const pixels =
                hits.data() + static_cast<std::size_t>(y0 + row) * width + static_cast<std::size_t>(x0);
            for (int column = 0; column < columns; column += 4)
                __builtin_prefetch(pixels + column, 1);
            __builtin_prefetch(pixels + columns - 1, 1);
        }
        accel.intersect_packet(rays, tile_hits, counters);
        store_tile_hits(camera, x0, y0, tile_hits, hits);
    });
}

// One frame as VIEWS.md times it: generate every ray from the camera, trace it, store its closest hit at its
// pixel. One task per row of tiles. An Embree row's tasks set flush-to-zero once, as Embree's manual and
// tutorials do (lancer/denormals.hpp); lancer's structures run in the IEEE mode.
void trace_frame(const Accel& accel, const PinholeCamera& camera, std::vector<Hit>& hits,
                 tbb::task_arena& arena) {
    const bool flush_denormals = accel.name().starts_with("embree");
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, tile_rows(camera), 1),
                          [&](const tbb::blocked_range<int>& rows) {
                              std::optional<DenormalsFlushed> flushed;
                              if (flush_denormals) flushed.emplace();
                              trace_tiles(accel, camera, rows.begin(), rows.end(), hits);
                          });
    });
}

// One view of one mesh: its rays (in pixel order for the primary view, as its hits are stored) and the
// first structure's answers, which every other structure must give. The shadow view's reference is the
// first structure's closest hits: a ray is occluded when it has one.
struct ViewRays {
    BenchView view;
    std::vector<Ray> rays;
    std::vector<Hit> reference;
    std::string reference_name;
};

// One structure's answers on a view through the path that is timed, with its traversal counts.
struct ViewAnswers {
    std::vector<Hit> hits;
    std::vector<std::uint8_t> occluded;
    TraversalCounters counters;
    std::size_t hit_count = 0;  // rays that hit (primary, diffuse) or are occluded (shadow)
};

ViewAnswers answer_view(const Accel& accel, const ViewRays& view, const PinholeCamera& camera) {
    ViewAnswers answers;
    answers.hits.resize(view.rays.size());
    if (view.view == BenchView::Primary) {
        trace_tiles(accel, camera, 0, tile_rows(camera), answers.hits, &answers.counters);
    } else if (view.view == BenchView::Diffuse) {
        accel.intersect(view.rays, answers.hits, &answers.counters);
    } else {
        answers.occluded.resize(view.rays.size());
        accel.occluded(view.rays, answers.occluded, &answers.counters);
        answers.hit_count =
            static_cast<std::size_t>(std::count(answers.occluded.begin(), answers.occluded.end(), 1));
        return answers;
    }
    answers.hit_count = static_cast<std::size_t>(
        std::count_if(answers.hits.begin(), answers.hits.end(), [](const Hit& hit) { return hit.hit(); }));
    return answers;
}

// The canonical view's rays, and the secondary sets asked for, made from lancer's closest hits on it (any
// structure's, bit for bit: the binary BVH's, whose build is quick).
std::vector<ViewRays> make_views(const std::vector<BenchView>& wanted, const Geometry& geometry,
                                 const PinholeCamera& camera, bool watertight) {
    const std::vector<Ray> primary = camera.pixel_centre_rays(0, 0, camera.width(), camera.height());
    std::vector<Hit> primary_hits;
    std::vector<ViewRays> views;
    for (BenchView view : wanted) {
        if (view == BenchView::Primary) {
            views.push_back({view, primary, {}, {}});
            continue;
        }
        if (primary_hits.empty()) {
            primary_hits.resize(primary.size());
            build_timed(AccelChoice{"bvh", watertight, {}}, geometry).accel->intersect(primary, primary_hits);
        }
        std::vector<Ray> rays =
            secondary_view_rays(view == BenchView::Diffuse ? SecondaryView::Diffuse : SecondaryView::Shadow,
                                geometry, primary, primary_hits);
        // No camera ray hit (a mesh seen edge on): nothing to time.
        if (rays.empty()) {
            fmt::print("bench: the {} view has no rays: no camera ray hits the mesh\n", view_name(view));
            continue;
        }
        views.push_back({view, std::move(rays), {}, {}});
    }
    return views;
}

std::string cpu_name() {
    std::ifstream cpuinfo("/proc/cpuinfo");
    std::string line;
    while (std::getline(cpuinfo, line)) {
        if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
    }
    return "unknown CPU";
}

void write_json(const std::string& file, const std::vector<Record>& records) {
    std::string json = "[\n";
    for (std::size_t i = 0; i < records.size(); ++i) {
        const Record& r = records[i];
        json += fmt::format(
            "  {{\"mesh\": \"{}\", \"view\": \"{}\", \"triangles\": {}, \"accel\": \"{}\", \"threads\": {}, "
            "\"build_ms\": "
            "{:.3f}, "
            "\"memory_bytes\": {}, \"geometry_bytes\": {}, \"mrays_per_s\": {:.4f}, \"mrays_min\": {:.4f}, "
            "\"mrays_max\": {:.4f}, \"hit_fraction\": {:.6f}, \"nodes_per_ray\": {}, \"prims_per_ray\": "
            "{}, \"mismatches\": {}}}{}\n",
            r.mesh, view_name(r.view), r.triangles, r.accel, r.threads, r.build_ms, r.memory_bytes,
            r.geometry_bytes, r.mrays_median, r.mrays_min, r.mrays_max, r.hit_fraction,
            r.counted ? fmt::format("{:.4f}", r.nodes_per_ray) : "null",
            r.counted ? fmt::format("{:.4f}", r.prims_per_ray) : "null", r.mismatches,
            i + 1 < records.size() ? "," : "");
    }
    json += "]\n";
    try {
        fmt::output_file(file).print("{}", json);
    } catch (const std::system_error& error) {
        throw InputError(file + ": " + error.what());
    }
}

// Horizontal bars, one group per mesh, one bar per structure and thread count, labelled with the value.
void write_svg(const std::string& file, const std::vector<Record>& records) {
    constexpr int kBarHeight = 16, kLabelWidth = 230, kChartWidth = 520, kGroupGap = 28;
    double best = 0.0;
    for (const Record& r : records)
        best = std::max(best, r.mrays_median);
    const std::array<const char*, 6> palette = {"#4c72b0", "#dd8452", "#55a868",
                                                "#c44e52", "#8172b3", "#937860"};
    std::vector<std::string> accels;
    for (const Record& r : records) {
        if (std::find(accels.begin(), accels.end(), r.accel) == accels.end()) accels.push_back(r.accel);
    }
    std::string body;
    int y = 40;
    std::string current_mesh;
    for (const Record& r : records) {
        if (r.mesh != current_mesh) {
            current_mesh = r.mesh;
            y += kGroupGap / 2;
            body += fmt::format("<text x=\"8\" y=\"{}\" font-weight=\"bold\">{} ({} triangles)</text>\n", y,
                                r.mesh, r.triangles);
            y += 8;
        }
        const auto colour =
            static_cast<std::size_t>(std::find(accels.begin(), accels.end(), r.accel) - accels.begin());
        const double width = best > 0.0 ? kChartWidth * r.mrays_median / best : 0.0;
        body += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{}{}, {} thread{}</text>\n",
                            kLabelWidth - 6, y + kBarHeight - 4, r.accel,
                            r.view == BenchView::Primary ? "" : fmt::format(", {}", view_name(r.view)),
                            r.threads, r.threads > 1 ? "s" : "");
        body += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{:.1f}\" height=\"{}\" fill=\"{}\"/>\n",
                            kLabelWidth, y, width, kBarHeight - 2, palette[colour % palette.size()]);
        body += fmt::format("<text x=\"{:.1f}\" y=\"{}\">{:.2f}</text>\n", kLabelWidth + width + 4,
                            y + kBarHeight - 4, r.mrays_median);
        y += kBarHeight;
    }
    const int height = y + 20;
    const std::string svg = fmt::format(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" "
        "font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
        "<text x=\"8\" y=\"20\" font-size=\"14\">lancer bench: Mrays/s on the views of VIEWS.md (median of "
        "the "
        "frames)</text>\n{}</svg>\n",
        kLabelWidth + kChartWidth + 80, height, body);
    try {
        fmt::output_file(file).print("{}", svg);
    } catch (const std::system_error& error) {
        throw InputError(file + ": " + error.what());
    }
}

void run(const BenchOptions& options) {
    options.device.require_available();
    const std::vector<int> thread_counts = parse_int_list(options.thread_list, "--threads");
    const std::vector<std::string> accels = parse_accels(options.accel_list);
    const std::vector<BenchMesh> meshes = load_meshes(options);
    if (options.device.cuda()) {
        std::vector<CudaBenchMesh> gpu_meshes;
        for (const BenchMesh& mesh : meshes)
            gpu_meshes.push_back({mesh.name, &mesh.scene});
        const std::vector<std::string> requested =
            options.accel_list == "all" ? std::vector<std::string>{"all"} : accels;
        run_cuda_bench(options.device, gpu_meshes,
                       {requested, options.size, options.frames, !options.moller_trumbore, options.settings});
        return;
    }

    const std::vector<BenchView> views = parse_views(options.view_list);
    std::string isas;
    for (SimdIsa isa : available_isas())
        isas += (isas.empty() ? "" : ", ") + std::string(isa_name(isa));
    fmt::print(
        "lancer bench: {}, {} hardware threads; {} {}; SIMD kernels: {}; {}x{} canonical view, {} frames "
        "after 1 warm-up\n",
        cpu_name(), std::thread::hardware_concurrency(), LANCER_COMPILER, LANCER_BUILD_FLAGS,
        isas.empty() ? "none" : isas, options.size, options.size, options.frames);
    fmt::print(
        "{:<16} {:<7} {:>9} {:<8} {:>3} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>6} {:>8} {:>8}\n",
        "mesh", "view", "triangles", "accel", "thr", "build ms", "Mtris/s", "accel MB", "tris MB", "Mrays/s",
        "min", "max", "hits", "nodes/r", "prims/r");
    // Embree 3 picks its builder from the scene flags first (Scene::createTriangleAccel): the robust mode
    // builds Triangle4v leaves with the plain SAH builder, so a HIGH row's build time is not a spatial
    // split build's, and comparing it with bvh.spatial_splits would flatter lancer.
    const bool embree_requested =
        std::ranges::any_of(accels, [](const std::string& name) { return name.starts_with("embree"); });
    if (embree_requested && !options.moller_trumbore)
        fmt::print(
            "bench: Embree's robust mode (the watertight test) builds without spatial splits whatever "
            "embree.quality says; --moller-trumbore times its HIGH build\n");

    std::vector<Record> records;
    bool agreement_failed = false;
    for (const BenchMesh& mesh : meshes) {
        const SceneGeometry geometry(mesh.scene);
        const PinholeCamera camera(canonical_view(geometry.view().bounds(), options.size, options.size));
        std::vector<ViewRays> mesh_views =
            make_views(views, geometry.view(), camera, !options.moller_trumbore);
        for (const std::string& name : accels) {
            AccelChoice choice{name, !options.moller_trumbore, options.settings};
            const BuiltAccel built = build_timed(choice, geometry.view());
            // The build again inside an arena of each thread count, so that the build figure is that
            // count's: once per structure and count, whatever the views.
            std::vector<double> build_ms;
            for (int threads : thread_counts) {
                tbb::task_arena arena(threads);
                build_ms.push_back(
                    arena.execute([&] { return build_timed(choice, geometry.view()).build_ms; }));
            }
            for (ViewRays& view : mesh_views) {
                // Validate before timing, through the timed path: the same answers as the first structure
                // measured.
                ViewAnswers answers = answer_view(*built.accel, view, camera);
                if (view.reference_name.empty()) {
                    view.reference_name = name;
                    view.reference = answers.hits;  // a shadow view's: the closest hits, made just below
                    if (view.view == BenchView::Shadow) built.accel->intersect(view.rays, view.reference);
                }
                const Agreement agreement =
                    view.view == BenchView::Shadow
                        ? compare_occlusion(view.rays, view.reference, answers.occluded)
                        : compare_hits(view.rays, view.reference, answers.hits);
                // Embree is a peer with its own triangle test, not one of lancer's kernels: its row is kept,
                // with the count of rays on which it answers otherwise.
                if (agreement.mismatches > 0 && name.starts_with("embree")) {
                    fmt::print(
                        "bench: {} differs from {} on {}, {} view, on {} of {} rays (its own triangle "
                        "test); first: {}\n",
                        name, view.reference_name, mesh.name, view_name(view.view), agreement.mismatches,
                        agreement.rays, agreement.first_mismatch);
                } else if (agreement.mismatches > 0) {
                    fmt::print(stderr, "bench: {} disagrees with {} on {}, {} view: {}\n", name,
                               view.reference_name, mesh.name, view_name(view.view), agreement.summary());
                    agreement_failed = true;
                    continue;
                }
                const double ray_count = static_cast<double>(view.rays.size());
                for (std::size_t t = 0; t < thread_counts.size(); ++t) {
                    const int threads = thread_counts[t];
                    tbb::task_arena arena(threads);
                    std::vector<double> mrays;
                    for (int frame = -1; frame < options.frames; ++frame) {  // frame -1: the warm-up
                        Stopwatch watch;
                        if (view.view == BenchView::Primary)
                            trace_frame(*built.accel, camera, answers.hits, arena);
                        else if (view.view == BenchView::Shadow)
                            occluded_parallel(*built.accel, view.rays, answers.occluded, arena);
                        else
                            intersect_parallel(*built.accel, view.rays, answers.hits, arena);
                        if (frame >= 0) mrays.push_back(ray_count / (watch.elapsed_ms() * 1e3));
                    }
                    std::sort(mrays.begin(), mrays.end());
                    Record record;
                    record.mesh = mesh.name;
                    record.view = view.view;
                    record.triangles = geometry.triangle_count();
                    record.accel = name;
                    record.threads = threads;
                    record.build_ms = build_ms[t];
                    record.memory_bytes = built.accel->memory_bytes();
                    record.geometry_bytes = geometry.view().triangles.size() * sizeof(Triangle) +
                                            geometry.view().spheres.size() * sizeof(Sphere);
                    record.mrays_median = mrays[mrays.size() / 2];
                    record.mrays_min = mrays.front();
                    record.mrays_max = mrays.back();
                    record.hit_fraction = static_cast<double>(answers.hit_count) / ray_count;
                    record.nodes_per_ray = static_cast<double>(answers.counters.nodes_visited) / ray_count;
                    record.prims_per_ray = static_cast<double>(answers.counters.prims_tested) / ray_count;
                    record.counted = answers.counters.nodes_visited > 0;
                    record.mismatches = agreement.mismatches;
                    fmt::print(
                        "{:<16} {:<7} {:>9} {:<8} {:>3} {:>10.1f} {:>9.2f} {:>9.2f} {:>9.2f} {:>9.2f} "
                        "{:>9.2f} "
                        "{:>9.2f} {:>5.1f}% {:>8} {:>8}\n",
                        record.mesh, view_name(record.view), record.triangles, record.accel, threads,
                        record.build_ms, static_cast<double>(record.triangles) / (record.build_ms * 1e3),
                        static_cast<double>(record.memory_bytes) / (1024.0 * 1024.0),
                        static_cast<double>(record.geometry_bytes) / (1024.0 * 1024.0), record.mrays_median,
                        record.mrays_min, record.mrays_max, 100.0 * record.hit_fraction,
                        per_ray(record.nodes_per_ray, record.counted),
                        per_ray(record.prims_per_ray, record.counted));
                    std::fflush(stdout);
                    records.push_back(record);
                }
            }
        }
    }
    if (!options.json_file.empty()) write_json(options.json_file, records);
    if (!options.svg_file.empty()) write_svg(options.svg_file, records);
    if (agreement_failed)
        throw CheckFailure("bench: structures disagree (see above); figures not trustworthy");
}

// One structure's strong scaling over the ranks of an mpirun job (lancer bench --mpi).
struct ScalingRecord {
    std::string mesh;
    std::string accel;
    int threads = 0;
    int ranks = 0;
    double mrays_one_rank = 0.0, mrays_all_ranks = 0.0;

    // t_1 / (N t_N): 1 when N ranks trace N times as fast as one.
    [[nodiscard]] double efficiency() const { return mrays_all_ranks / (mrays_one_rank * ranks); }
};

double median_of(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    return values[values.size() / 2];
}

// lancer bench --mpi, under mpirun: the canonical view rendered with flat shading (its primary rays, through
// the renderer's tiles and packets) by rank 0 alone while the others wait, then by every rank from the shared
// tile counter (Job::render), frame after frame; Mrays/s of each, and the parallel efficiency t_1 / (N t_N)
// (docs/distributed.md). Every rank loads the meshes and builds the structures.
void run_mpi(const BenchOptions& options) {
    const Job& job = Job::get();
    if (!job.distributed())
        throw InputError("--mpi: run it under mpirun with 2 or more ranks (mpirun -np 2 lancer bench --mpi)");
    if (options.view_list != "primary" || options.device.cuda())
        throw InputError("--mpi measures the primary view on the CPU: leave out --view and --device");
    const std::vector<int> thread_counts = parse_int_list(options.thread_list, "--threads");
    const std::vector<std::string> accels = parse_accels(options.accel_list);
    std::vector<BenchMesh> meshes;
    job.on_every_rank("loading the meshes", [&] { meshes = load_meshes(options); });
    if (job.is_root()) {
        fmt::print(
            "lancer bench --mpi: {} ranks; rank 0 on {}, {} hardware threads; {}x{} canonical view, flat "
            "shading, {} frames after 1 warm-up\n",
            job.size(), cpu_name(), std::thread::hardware_concurrency(), options.size, options.size,
            options.frames);
        fmt::print("{:<16} {:<14} {:>3} {:>5} {:>14} {:>14} {:>10}\n", "mesh", "accel", "thr", "ranks",
                   "1 rank Mrays/s", "all Mrays/s", "efficiency");
    }
    std::vector<ScalingRecord> records;
    for (const BenchMesh& mesh : meshes) {
        const SceneGeometry geometry(mesh.scene);
        const Camera camera = canonical_view(geometry.view().bounds(), options.size, options.size);
        const double rays = static_cast<double>(options.size) * static_cast<double>(options.size);
        for (const std::string& name : accels) {
            BuiltAccel built;
            job.on_every_rank("building " + name, [&] {
                built = build_timed({name, !options.moller_trumbore, options.settings}, geometry.view());
            });
            for (const int threads : thread_counts) {
                RenderOptions render_options;
                render_options.mode = ShadingMode::Flat;
                render_options.threads = threads;
                std::vector<double> alone_ms, all_ms;
                for (int frame = -1; frame < options.frames; ++frame) {  // frame -1: the warm-up
                    job.barrier();
                    Stopwatch alone;
                    if (job.is_root())
                        static_cast<void>(render(mesh.scene, geometry, *built.accel, camera, render_options));
                    job.barrier();
                    const double alone_elapsed = alone.elapsed_ms();
                    RenderStats stats;
                    Stopwatch all;
                    static_cast<void>(
                        job.render(mesh.scene, geometry, *built.accel, camera, render_options, stats));
                    const double all_elapsed = job.max_over_ranks(all.elapsed_ms());
                    if (frame >= 0) alone_ms.push_back(alone_elapsed), all_ms.push_back(all_elapsed);
                }
                ScalingRecord record{mesh.name,
                                     name,
                                     threads,
                                     job.size(),
                                     rays / (median_of(alone_ms) * 1e3),
                                     rays / (median_of(all_ms) * 1e3)};
                if (job.is_root()) {
                    fmt::print("{:<16} {:<14} {:>3} {:>5} {:>14.2f} {:>14.2f} {:>10.2f}\n", record.mesh,
                               record.accel, threads, record.ranks, record.mrays_one_rank,
                               record.mrays_all_ranks, record.efficiency());
                }
                records.push_back(record);
            }
        }
    }
    if (!job.is_root() || options.json_file.empty()) return;
    std::string json = "[\n";
    for (std::size_t i = 0; i < records.size(); ++i) {
        const ScalingRecord& r = records[i];
        json += fmt::format(
            "  {{\"mesh\": \"{}\", \"view\": \"primary\", \"accel\": \"{}\", \"threads\": {}, \"ranks\": {}, "
            "\"mrays_one_rank\": {:.4f}, \"mrays_all_ranks\": {:.4f}, \"parallel_efficiency\": {:.4f}}}{}\n",
            r.mesh, r.accel, r.threads, r.ranks, r.mrays_one_rank, r.mrays_all_ranks, r.efficiency(),
            i + 1 < records.size() ? "," : "");
    }
    json += "]\n";
    try {
        fmt::output_file(options.json_file).print("{}", json);
    } catch (const std::system_error& error) {
        throw InputError(options.json_file + ": " + error.what());
    }
}

}  // namespace

void add_bench_command(CLI::App& app) {
    auto options = std::make_shared<BenchOptions>();
    CLI::App* command = app.add_subcommand(
        "bench", "Mrays/s of every structure on the views of VIEWS.md, Embree beside lancer");
    command->add_option("--mesh", options->meshes,
                        "Mesh file (repeatable; default: the Stanford meshes of ../shared/data/meshes, else "
                        "generated meshes of 70k, 350k and 870k triangles)");
    command->add_option("--accel", options->accel_list, "Comma-separated structures, or all")
        ->capture_default_str();
    command->add_option("--threads", options->thread_list, "Comma-separated thread counts")
        ->capture_default_str();
    command
        ->add_option("--view", options->view_list,
                     "Comma-separated views of VIEWS.md: primary (camera rays, closest hit), diffuse (4 "
                     "cosine-weighted rays per hit, closest hit), shadow (1 ray per hit to a point light, "
                     "any hit)")
        ->capture_default_str();
    command->add_option("--size", options->size, "Image side in pixels")
        ->check(CLI::Range(1, 16384))
        ->capture_default_str();
    command->add_option("--frames", options->frames, "Timed frames (median, min, max)")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    command->add_flag("--moller-trumbore", options->moller_trumbore,
                      "Moller-Trumbore instead of the default watertight test (Embree then runs its fast, "
                      "non-robust test: the two leak through different edges, so they may disagree)");
    command->add_option("--set", options->settings,
                        "Structure option KEY=VALUE (repeatable; `lancer info --options` lists them)");
    add_memory_limit_option(*command);
    command->add_option("--json", options->json_file,
                        "Write one record per mesh, structure and thread count");
    command->add_option("--svg", options->svg_file, "Draw the Mrays/s bars");
    command->add_flag("--mpi", options->mpi,
                      "Under mpirun: the canonical view by rank 0 alone and by every rank, with the parallel "
                      "efficiency (docs/distributed.md)");
    options->device.add_options(*command);
    command->callback([options] { options->mpi ? run_mpi(*options) : run(*options); });
}

}  // namespace lancer::cli
