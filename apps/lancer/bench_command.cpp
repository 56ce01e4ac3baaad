// lancer bench: the throughput of every structure on the views of shared/bench/VIEWS.md, Embree beside
// lancer in the same process on the same rays and threads. Every structure's answers are checked against
// the first structure's before it is timed, ray by ray; a disagreement fails the bench (exit code 1). The
// structures of a mesh take turns frame by frame, so that their ratios hold on a machine whose speed drifts.
// The timed paths are in bench_trace.hpp (the secondary views go 4096 consecutive rays a task through
// intersect_parallel and occluded_parallel: Embree's rows then call rtcIntersectN or rtcOccludedN, or the
// stream calls rtcIntersect1M or rtcOccluded1M, without the COHERENT flag), the JSON and SVG reports in
// bench_report.hpp.
#include <fmt/core.h>
#include <fmt/os.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <thread>

#include "bench_animate.hpp"
#include "bench_instances.hpp"
#include "bench_report.hpp"
#include "bench_trace.hpp"
#include "commands.hpp"
#include "common.hpp"
#include "cuda_device.hpp"
#include "distributed.hpp"
#include "lancer/agreement.hpp"
#include "lancer/camera.hpp"
#include "lancer/generate.hpp"
#include "lancer/isa.hpp"
#include "lancer/parallel.hpp"

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
    int subdivide = 0;  // levels of midpoint subdivision of every mesh (4^N times its triangles)
    bool moller_trumbore = false;
    std::vector<std::string> settings;
    std::string json_file;
    std::string svg_file;
    bool mpi = false;
    int animate = 0;
    int instances = 0;
    DeviceChoice device;
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
    for (BenchMesh& mesh : meshes) {
        if (options.subdivide == 0) continue;
        for (TriangleMesh& part : mesh.scene.meshes) {
            for (int level = 0; level < options.subdivide; ++level)
                part = subdivided(part);
        }
        mesh.name += fmt::format("/s{}", options.subdivide);
    }
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

// A structure of one mesh's run, built, with its build time on each thread count.
struct BenchedAccel {
    std::string name;
    BuiltAccel built;
    std::vector<double> build_ms;
};

std::string cpu_name() {
    std::ifstream cpuinfo("/proc/cpuinfo");
    std::string line;
    while (std::getline(cpuinfo, line)) {
        if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
    }
    return "unknown CPU";
}

void run(const BenchOptions& options) {
    options.device.require_available();
    const std::vector<int> thread_counts = parse_int_list(options.thread_list, "--threads");
    const std::vector<std::string> accels = parse_accels(options.accel_list);
    if (options.animate > 0 && (options.view_list != "primary" || options.device.cuda()))
        throw InputError("--animate times the primary view on the CPU: leave out --view and --device");
    if (options.instances > 0 && (options.animate > 0 || options.device.cuda()))
        throw InputError(
            "--instances times lancer's and Embree's two-level scenes on the CPU: leave out "
            "--animate and --device");
    if (options.instances > 0 && options.meshes.size() > 1)
        throw InputError("--instances places one mesh: give at most one --mesh");
    const std::vector<BenchMesh> meshes = load_meshes(options);
    if (options.instances > 0) {
        fmt::print("lancer bench --instances: {}, {} hardware threads; {} {}\n", cpu_name(),
                   std::thread::hardware_concurrency(), LANCER_COMPILER, LANCER_BUILD_FLAGS);
        const std::vector<std::string> instanced_accels =
            options.accel_list == "all" ? std::vector<std::string>{"bvh8",    "bvh8_packet", "embree",
                                                                   "embree8", "embree16",    "embree_stream"}
                                        : accels;
        run_instances_bench(
            meshes.front().name, meshes.front().scene,
            {options.instances, thread_counts, parse_views(options.view_list), instanced_accels, options.size,
             options.frames, !options.moller_trumbore, options.settings});
        return;
    }
    if (options.animate > 0) {
        fmt::print("lancer bench --animate: {}, {} hardware threads; {} {}\n", cpu_name(),
                   std::thread::hardware_concurrency(), LANCER_COMPILER, LANCER_BUILD_FLAGS);
        std::vector<AnimatedBenchMesh> animated;
        for (const BenchMesh& mesh : meshes)
            animated.push_back({mesh.name, &mesh.scene});
        run_animated_bench(animated, {options.animate, thread_counts, accels, options.size,
                                      !options.moller_trumbore, options.settings, options.json_file});
        return;
    }
    if (options.device.cuda()) {
        std::vector<CudaBenchMesh> gpu_meshes;
        for (const BenchMesh& mesh : meshes)
            gpu_meshes.push_back({mesh.name, &mesh.scene});
        const std::vector<std::string> requested =
            options.accel_list == "all" ? std::vector<std::string>{"all"} : accels;
        run_cuda_bench(options.device, gpu_meshes,
                       {requested, parse_views(options.view_list), options.size, options.frames,
                        !options.moller_trumbore, options.settings});
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

    std::vector<BenchRecord> records;
    bool agreement_failed = false;
    for (const BenchMesh& mesh : meshes) {
        const SceneGeometry geometry(mesh.scene);
        const PinholeCamera camera(canonical_view(geometry.view().bounds(), options.size, options.size));
        std::vector<ViewRays> mesh_views =
            make_views(views, geometry.view(), camera, !options.moller_trumbore);
        // Every structure of the mesh is built before any is timed, so that their frames can take turns.
        std::vector<BenchedAccel> benched;
        for (const std::string& name : accels) {
            AccelChoice choice{name, !options.moller_trumbore, options.settings};
            BenchedAccel entry{name, build_timed(choice, geometry.view()), {}};
            // The build again on each thread count, so that the build figure is that count's: once per
            // structure and count, whatever the views.
            for (int threads : thread_counts) {
                run_with_threads(threads, [&] {
                    entry.build_ms.push_back(build_timed(choice, geometry.view()).build_ms);
                });
            }
            benched.push_back(std::move(entry));
        }
        for (ViewRays& view : mesh_views) {
            // Validate before timing, through the timed path: the same answers as the first structure
            // measured. A structure that disagrees is not timed.
            std::vector<ViewAnswers> answers;
            std::vector<Agreement> agreements;
            std::vector<bool> timed;
            for (const BenchedAccel& entry : benched) {
                answers.push_back(answer_view(*entry.built.accel, view, camera));
                if (view.reference_name.empty()) {
                    view.reference_name = entry.name;
                    view.reference =
                        answers.back().hits;  // a shadow view's: the closest hits, made just below
                    if (view.view == BenchView::Shadow)
                        entry.built.accel->intersect(view.rays, view.reference);
                }
                agreements.push_back(
                    view.view == BenchView::Shadow
                        ? compare_occlusion(view.rays, view.reference, answers.back().occluded)
                        : compare_hits(view.rays, view.reference, answers.back().hits));
                const Agreement& agreement = agreements.back();
                // Embree is a peer with its own triangle test, not one of lancer's kernels: its row is kept,
                // with the count of rays on which it answers otherwise.
                timed.push_back(agreement.mismatches == 0 || entry.name.starts_with("embree"));
                if (agreement.mismatches > 0 && entry.name.starts_with("embree")) {
                    fmt::print(
                        "bench: {} differs from {} on {}, {} view, on {} of {} rays (its own triangle "
                        "test); first: {}\n",
                        entry.name, view.reference_name, mesh.name, view_name(view.view),
                        agreement.mismatches, agreement.rays, agreement.first_mismatch);
                } else if (agreement.mismatches > 0) {
                    fmt::print(stderr, "bench: {} disagrees with {} on {}, {} view: {}\n", entry.name,
                               view.reference_name, mesh.name, view_name(view.view), agreement.summary());
                    agreement_failed = true;
                }
            }
            const double ray_count = static_cast<double>(view.rays.size());
            for (std::size_t t = 0; t < thread_counts.size(); ++t) {
                const int threads = thread_counts[t];
                std::vector<std::vector<double>> mrays(benched.size());
                // The structures take turns frame by frame, so that a machine whose speed drifts (a shared
                // VM: up to 40%) slows them alike and their ratios hold. One arena for every frame of this
                // count, its set-up outside the frames' clocks.
                run_with_threads(threads, [&] {
                    for (int frame = -1; frame < options.frames; ++frame) {  // frame -1: the warm-ups
                        for (std::size_t i = 0; i < benched.size(); ++i) {
                            if (!timed[i]) continue;
                            const Accel& accel = *benched[i].built.accel;
                            Stopwatch watch;
                            if (view.view == BenchView::Primary)
                                trace_frame(accel, camera, answers[i].hits);
                            else if (view.view == BenchView::Shadow)
                                occluded_parallel(accel, view.rays, answers[i].occluded);
                            else
                                intersect_parallel(accel, view.rays, answers[i].hits);
                            if (frame >= 0) mrays[i].push_back(ray_count / (watch.elapsed_ms() * 1e3));
                        }
                    }
                });
                for (std::size_t i = 0; i < benched.size(); ++i) {
                    if (!timed[i]) continue;
                    std::sort(mrays[i].begin(), mrays[i].end());
                    const ViewAnswers& answer = answers[i];
                    BenchRecord record;
                    record.mesh = mesh.name;
                    record.view = view.view;
                    record.triangles = geometry.triangle_count();
                    record.accel = benched[i].name;
                    record.threads = threads;
                    record.build_ms = benched[i].build_ms[t];
                    record.memory_bytes = benched[i].built.accel->memory_bytes();
                    record.geometry_bytes = geometry.view().triangles.size() * sizeof(Triangle) +
                                            geometry.view().spheres.size() * sizeof(Sphere);
                    record.mrays_median = mrays[i][mrays[i].size() / 2];
                    record.mrays_min = mrays[i].front();
                    record.mrays_max = mrays[i].back();
                    record.hit_fraction = static_cast<double>(answer.hit_count) / ray_count;
                    record.nodes_per_ray = static_cast<double>(answer.counters.nodes_visited) / ray_count;
                    record.prims_per_ray = static_cast<double>(answer.counters.prims_tested) / ray_count;
                    record.counted = answer.counters.nodes_visited > 0;
                    record.mismatches = agreements[i].mismatches;
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
    if (!options.json_file.empty()) write_bench_json(options.json_file, records);
    if (!options.svg_file.empty()) write_bench_svg(options.svg_file, records);
    if (agreement_failed)
        throw CheckFailure("bench: structures disagree (see above); figures not trustworthy");
}

// One structure's strong scaling over the ranks of an mpirun job (lancer bench --mpi).
struct ScalingBenchRecord {
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
    std::vector<ScalingBenchRecord> records;
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
                ScalingBenchRecord record{mesh.name,
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
        const ScalingBenchRecord& r = records[i];
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
    command
        ->add_option(
            "--subdivide", options->subdivide,
            "Split every triangle of every mesh into 4 at its edges' midpoints, N times: meshes of "
            "4^N times the triangles, the same shape (the dragon's 871k: 3.5M, 14M, 56M). Every structure "
            "of --accel is held at once: name few for large N, or bound --max-memory")
        ->check(CLI::Range(0, 4))
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
    command
        ->add_option(
            "--animate", options->animate,
            "Deform each mesh over N frames (a travelling sine wave, docs/accel/refit.md) and time, per "
            "frame and structure, its update (Accel::update: the BVHs refit; Embree rows use Embree's "
            "refit quality) and a full rebuild, each with a trace of the canonical view")
        ->check(CLI::Range(1, 10000));
    command
        ->add_option(
            "--instances", options->instances,
            "A two-level scene of N copies of the mesh (the first --mesh, default the bunny) under "
            "random rotations, scales and positions: --accel names the objects' structures and Embree's "
            "calls on its own two-level scene (default bvh8, bvh8_packet, embree, embree8, embree16, "
            "embree_stream); the views traced, then every instance moved and the top level updated "
            "(docs/accel/instances.md)")
        ->check(CLI::Range(1, 100000000));
    options->device.add_options(*command);
    command->callback([options] { options->mpi ? run_mpi(*options) : run(*options); });
}

}  // namespace lancer::cli
