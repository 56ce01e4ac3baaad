// lancer render [SCENE]: renders a scene (the authored default scene when none is given) to PNG or OpenEXR,
// then prints a summary: sizes, timings, rays by kind and Mrays/s; with --beside NAME, the same frame
// rendered again with structure NAME (Embree's, typically) and its Mrays/s beside the first. A scene whose
// graph places a mesh several times (glTF's nodes), or --instances N, renders as instances, each mesh built
// once (InstancedWorld).
#include <fmt/core.h>

#include <cctype>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "commands.hpp"
#include "common.hpp"
#include "cuda_device.hpp"
#include "distributed.hpp"
#include "lancer/animate.hpp"
#include "lancer/generate.hpp"
#include "lancer/render.hpp"
#include "lancer/world.hpp"

namespace lancer::cli {
namespace {

struct RenderCommandOptions {
    std::string scene_file = LANCER_DEFAULT_SCENE;
    std::string output = "render.png";
    std::string size;
    ShadingMode mode = ShadingMode::Whitted;
    AccelChoice accel;
    std::string beside;  // a second structure that renders the same frame, for its Mrays/s
    DeviceChoice device;
    int threads = 0;
    int samples_per_pixel = 4;
    int max_depth = 5;
    float min_weight = 1.0f / 512.0f;
    bool fresnel = false;
    int animate = 0;    // frames of the animation; 0: one still image
    int instances = 0;  // --instances: the scene's meshes placed this many times in all; 0: as the file says
    std::vector<std::string> with_meshes;  // --with: more meshes for --instances to place
};

enum class ImageFormat { Png, Exr };

// The format -o names by its extension, in any case; none for any other extension, which the option refuses
// before anything is loaded, rather than writing PNG bytes under a name that says otherwise.
std::optional<ImageFormat> image_format(const std::filesystem::path& file) {
    std::string extension = file.extension().string();
    for (char& c : extension)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (extension == ".png") return ImageFormat::Png;
    if (extension == ".exr") return ImageFormat::Exr;
    return std::nullopt;
}

// The file of frame `frame` of an animation: `pattern` with its one printf conversion for the frame number,
// %d or a zero-padded %0Nd, replaced. Throws InputError for a pattern without exactly one.
std::string frame_file(const std::string& pattern, int frame) {
    std::string file;
    int conversions = 0;
    for (std::size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] != '%') {
            file += pattern[i];
            continue;
        }
        std::size_t end = i + 1;
        const bool zero_padded = end < pattern.size() && pattern[end] == '0';
        int width = 0;
        while (end < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[end])) != 0 &&
               width < 100)
            width = 10 * width + (pattern[end++] - '0');
        if (end >= pattern.size() || pattern[end] != 'd' || width > 16) {
            throw InputError("--animate: -o '" + pattern +
                             "' must name each frame with one %d or %0Nd (N up to 16), as frame_%04d.png");
        }
        const std::string number = std::to_string(frame);
        if (static_cast<int>(number.size()) < width)
            file.append(static_cast<std::size_t>(width) - number.size(), zero_padded ? '0' : ' ');
        file += number;
        ++conversions;
        i = end;
    }
    if (conversions != 1) {
        throw InputError("--animate: -o '" + pattern +
                         "' must name each frame with one %d or %0Nd, as frame_%04d.png");
    }
    return file;
}

void write_image(const Image& image, const std::string& file) {
    try {
        if (image_format(file) == ImageFormat::Exr)
            write_exr(image, file);
        else
            write_png(image, file);
    } catch (const std::runtime_error& error) {
        throw InputError(error.what());
    }
}

// lancer render --animate N: the scene's meshes deformed by the sine wave of `lancer bench --animate`
// (lancer/animate.hpp) over N frames, frame f of the period written to -o's pattern; the structure updated
// (Accel::update) between frames, the camera that of the rest pose.
void render_animation(const RenderCommandOptions& options, World& world, const Camera& camera,
                      const RenderOptions& render_options) {
    const Scene rest = world.scene();
    const SineWave wave{rest.bounds(), options.animate};
    for (int frame = 0; frame < options.animate; ++frame) {
        const std::vector<std::vector<Vec3f>> moved = deformed_meshes(rest, wave, frame);
        std::vector<MeshVertices> moves;
        for (std::size_t mesh = 0; mesh < moved.size(); ++mesh)
            moves.push_back({mesh, moved[mesh]});
        const UpdateReport report = world.update_vertices(moves);
        RenderStats stats;
        const Image image = render(world, camera, render_options, &stats);
        const std::string file = frame_file(options.output, frame);
        write_image(image, file);
        fmt::print("frame {}: update {:.1f} ms ({}), render {:.1f} ms, wrote {}\n", frame, report.ms,
                   report.method == UpdateMethod::Refit ? "refit" : "rebuild", stats.trace_ms, file);
        std::fflush(stdout);
    }
}

void print_summary(const RenderCommandOptions& options, const PreparedScene& prepared, const Image& image,
                   const RenderStats& stats) {
    const Scene& scene = prepared.world.scene();
    const bool whitted = options.mode == ShadingMode::Whitted;
    fmt::print("{}: {}x{}{}, {} triangles, {} spheres, {} planes, {} lights\n", options.scene_file,
               image.width, image.height, whitted ? fmt::format(", {} spp", options.samples_per_pixel) : "",
               scene.triangle_count(), scene.spheres.size(), scene.planes.size(), scene.lights.size());
    fmt::print("load {:.1f} ms, accel {} build {:.1f} ms, render {:.1f} ms\n", prepared.load_ms,
               prepared.world.accel().name(), prepared.build_ms, stats.trace_ms);
    const double mrays_per_s = static_cast<double>(stats.total_rays()) / (stats.trace_ms * 1e3);
    if (whitted) {
        fmt::print("rays: {} primary, {} shadow, {} reflection, {} refraction; {} in all, {:.2f} Mrays/s\n",
                   stats.primary_rays, stats.shadow_rays, stats.reflection_rays, stats.refraction_rays,
                   stats.total_rays(), mrays_per_s);
    } else {
        fmt::print("rays: {} primary, {:.2f} Mrays/s\n", stats.primary_rays, mrays_per_s);
    }
    if (options.mode == ShadingMode::Heatmap) {
        const double rays = static_cast<double>(stats.counters.rays);
        fmt::print("per primary ray: {:.2f} nodes visited",
                   static_cast<double>(stats.counters.nodes_visited) / rays);
        // The GPU kernels count nodes only.
        if (!options.device.cuda())
            fmt::print(", {:.2f} primitives tested", static_cast<double>(stats.counters.prims_tested) / rays);
        fmt::print("\n");
    }
    fmt::print("wrote {}\n", options.output);
}

// The frame again with the structure --beside names, on the same geometry, triangle test and threads; its
// image is not written. Its ray counts are printed too when they differ (a peer's own triangle test may
// send a few shadow or secondary rays elsewhere).
void render_beside(const RenderCommandOptions& options, const World& world, const Camera& camera,
                   const RenderOptions& render_options, const RenderStats& stats) {
    AccelChoice choice = options.accel;
    choice.name = options.beside;
    const BuiltAccel other = build_timed(choice, world.geometry().view());
    RenderStats other_stats;
    static_cast<void>(
        render(world.scene(), world.geometry(), *other.accel, camera, render_options, &other_stats));
    const double mrays = static_cast<double>(stats.total_rays()) / (stats.trace_ms * 1e3);
    const double other_mrays = static_cast<double>(other_stats.total_rays()) / (other_stats.trace_ms * 1e3);
    fmt::print("beside: {} build {:.1f} ms, render {:.1f} ms, {:.2f} Mrays/s; {} at {:.2f}x of it\n",
               other.accel->name(), other.build_ms, other_stats.trace_ms, other_mrays, world.accel().name(),
               mrays / other_mrays);
    if (other_stats.total_rays() != stats.total_rays())
        fmt::print("beside: {} traced {} rays where {} traced {}\n", other.accel->name(),
                   other_stats.total_rays(), world.accel().name(), stats.total_rays());
}

// --instances N: the meshes of the scene (and of --with's files) become objects, placed N times in all, in
// turn, at `lancer bench --instances`' random placements, each object's box centre moved to that of all
// their boxes first; the scene's spheres, planes, lights and materials stay.
void place_at_random(const RenderCommandOptions& options, Scene& scene) {
    for (const std::string& file : options.with_meshes) {
        LoadedScene more = load_timed(file);
        for (TriangleMesh& mesh : more.scene.meshes) {
            mesh.material = 0;  // the scene's default material: the other file's are not carried over
            mesh.material_ids.clear();
            scene.meshes.push_back(std::move(mesh));
        }
    }
    if (scene.meshes.empty())
        throw InputError("--instances: " + options.scene_file + " has no mesh to place");
    scene.instanced_meshes = std::move(scene.meshes);
    scene.meshes.clear();
    Box3f all;
    std::vector<Vec3f> centres;
    for (const TriangleMesh& mesh : scene.instanced_meshes) {
        Box3f box;
        for (const Vec3f& p : mesh.positions)
            box.extend(p);
        centres.push_back(box.center());
        all.extend(box);
    }
    const std::vector<Transform> placements = random_placements(all, options.instances);
    for (std::size_t i = 0; i < placements.size(); ++i) {
        const auto mesh = static_cast<std::uint32_t>(i % scene.instanced_meshes.size());
        scene.instances.push_back(
            {mesh, placements[i] * Transform::translation(all.center() - centres[mesh])});
    }
}

void print_instanced_summary(const RenderCommandOptions& options, const std::string& accel,
                             const InstancedWorld& world, double load_ms, const Image& image,
                             const RenderStats& stats) {
    const Scene& scene = world.scene();
    fmt::print("{}: {}x{}, {} objects placed by {} instances, {} instanced triangles\n", options.scene_file,
               image.width, image.height, scene.instanced_meshes.size(), scene.instances.size(),
               scene.instanced_triangle_count());
    fmt::print("load {:.1f} ms, objects {} and top level build {:.1f} ms, render {:.1f} ms\n", load_ms, accel,
               world.build_ms(), stats.trace_ms);
    fmt::print("rays: {} in all, {:.2f} Mrays/s\n", stats.total_rays(),
               static_cast<double>(stats.total_rays()) / (stats.trace_ms * 1e3));
    fmt::print("wrote {}\n", options.output);
}

// A scene whose meshes are placed by instances: each built once (InstancedWorld), rendered on the CPU.
void render_instanced(const RenderCommandOptions& options, LoadedScene loaded,
                      const RenderOptions& render_options) {
    if (options.device.cuda() || !options.beside.empty() || options.animate > 0 || Job::get().distributed())
        throw InputError(
            "a scene of instances renders on the CPU alone, in one process: leave out --device, "
            "--beside and --animate, and mpirun");
    Camera camera = loaded.scene.camera ? *loaded.scene.camera : canonical_view(loaded.scene.bounds());
    if (!options.size.empty()) std::tie(camera.width, camera.height) = parse_size(options.size);
    // An instance visit traces one ray: a packet structure (render's default) would be traced through the
    // bvh8 it holds after a longer build, so bvh8 unless --accel names one.
    const std::string accel = options.accel.name_option->count() == 0 ? "bvh8" : options.accel.name;
    std::optional<InstancedWorld> world;
    try {
        world.emplace(std::move(loaded.scene), accel, options.accel.build_options());
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    } catch (const std::bad_alloc&) {
        throw out_of_memory("the instanced scene", "building " + accel);
    }
    RenderStats stats;
    const Image image = render(*world, camera, render_options, &stats);
    write_image(image, options.output);
    print_instanced_summary(options, accel, *world, loaded.load_ms, image, stats);
}

void run(RenderCommandOptions options) {
    if (options.device.cuda() && options.mode != ShadingMode::Flat && options.mode != ShadingMode::Heatmap)
        throw InputError("--device cuda renders --mode flat or heatmap only");
    // The GPU's kernels walk bvh and plucker.
    if (options.device.cuda() && options.accel.name_option->count() == 0) options.accel.name = "bvh";
    options.device.require_available();
    if (!options.beside.empty()) {
        if (options.device.cuda())
            throw InputError("--beside compares structures on the CPU: leave out --device cuda");
        // Before the first render, not after it.
        try {
            static_cast<void>(make_accel(options.beside));
        } catch (const std::invalid_argument& error) {
            throw InputError(std::string("--beside: ") + error.what());
        }
    }
    const Job& job = Job::get();
    if (job.distributed() && (options.device.cuda() || !options.beside.empty() || options.animate > 0))
        throw InputError(
            "under mpirun, lancer render runs on the CPU alone: leave out --device, --beside and --animate");
    if (options.animate > 0) {
        if (options.device.cuda() || !options.beside.empty())
            throw InputError("--animate renders on the CPU alone: leave out --device and --beside");
        static_cast<void>(frame_file(options.output, 0));  // a bad pattern before the scene is loaded
    }
    if (options.instances > 0 && std::filesystem::path(options.scene_file).extension() == ".plo")
        throw InputError("--instances places a scene's meshes: " + options.scene_file +
                         " is a stored octree");
    RenderOptions render_options;
    render_options.mode = options.mode;
    render_options.threads = options.threads;
    render_options.progress = stderr_is_terminal();
    render_options.samples_per_pixel = options.samples_per_pixel;
    render_options.max_depth = options.max_depth;
    render_options.min_weight = options.min_weight;
    render_options.fresnel = options.fresnel;
    // Every rank loads the scene and builds its structure (docs/distributed.md). A scene graph's meshes
    // placed several times stay instances (LoadOptions::keep_instances), and are rendered as such.
    std::optional<PreparedScene> prepared;
    std::optional<LoadedScene> instanced;
    job.on_every_rank("loading the scene", [&] {
        if (std::filesystem::path(options.scene_file).extension() == ".plo") {
            prepared = prepare_scene(options.scene_file, options.accel);
            return;
        }
        LoadedScene loaded = load_timed(options.scene_file, {.keep_instances = true});
        if (options.instances > 0) place_at_random(options, loaded.scene);
        if (loaded.scene.instances.empty())
            prepared = prepare_loaded(std::move(loaded), options.accel);
        else
            instanced = std::move(loaded);
    });
    if (instanced) {
        render_instanced(options, std::move(*instanced), render_options);
        return;
    }
    World& world = prepared->world;
    const Scene& scene = world.scene();

    Camera camera = scene.camera ? *scene.camera : canonical_view(scene.bounds());
    if (!options.size.empty()) std::tie(camera.width, camera.height) = parse_size(options.size);
    if (options.animate > 0) {
        render_animation(options, world, camera, render_options);
        return;
    }
    RenderStats stats;
    Image image;
    if (options.device.cuda()) {
        render_options.device = RenderDevice::Cuda;
        render_options.cuda_kernel = options.device.kernel_for(world.accel().name());
        try {
            image = render(world, camera, render_options, &stats);
        } catch (const CudaError& error) {
            throw InputError(std::string("--device cuda: ") + error.what());
        } catch (const std::invalid_argument& error) {
            throw InputError(std::string("--device cuda: ") + error.what());
        }
    } else {
        image = job.render(scene, world.geometry(), world.accel(), camera, render_options, stats);
    }
    if (!job.is_root()) return;  // rank 0 writes the picture and the summary
    write_image(image, options.output);
    print_summary(options, *prepared, image, stats);
    if (!options.beside.empty()) render_beside(options, world, camera, render_options, stats);
}

}  // namespace

void add_render_command(CLI::App& app) {
    auto options = std::make_shared<RenderCommandOptions>();
    CLI::App* command = app.add_subcommand("render", "Render a scene to PNG or OpenEXR");
    command->add_option(
        "scene", options->scene_file,
        "Scene or mesh file, or a .plo octree from `lancer convert` (default: the demo scene)");
    command
        ->add_option("-o,--output", options->output,
                     "Image to write: 8-bit sRGB PNG when it ends in .png, linear half-float OpenEXR when it "
                     "ends in .exr")
        ->capture_default_str()
        ->check(CLI::Validator(
            [](const std::string& file) {
                return image_format(file) ? std::string()
                                          : "'" + file + "' is neither a .png nor an .exr file";
            },
            ""));
    command->add_option("--size", options->size, "Image size WIDTHxHEIGHT (default: the scene's camera)");
    const std::vector<std::pair<std::string, ShadingMode>> modes = {{"whitted", ShadingMode::Whitted},
                                                                    {"flat", ShadingMode::Flat},
                                                                    {"normal", ShadingMode::Normal},
                                                                    {"depth", ShadingMode::Depth},
                                                                    {"heatmap", ShadingMode::Heatmap}};
    command
        ->add_option("--mode", options->mode,
                     "Shading: whitted (default: shadows, reflection, refraction), flat, normal, depth or "
                     "heatmap (nodes per ray)")
        ->transform(one_of(modes));
    command->add_option("--spp", options->samples_per_pixel, "Whitted mode: stratified samples per pixel")
        ->capture_default_str()
        ->check(CLI::Range(1, 4096));
    command
        ->add_option("--max-depth", options->max_depth, "Whitted mode: ray-tree depth, the eye ray being 1")
        ->capture_default_str()
        ->check(CLI::Range(1, 64));
    command
        ->add_option("--min-weight", options->min_weight,
                     "Whitted mode: cut off reflected and refracted rays whose weight is not above this "
                     "(0: trace them all, as the SPD asks)")
        ->capture_default_str()
        ->check(CLI::Range(0.0f, 1.0f));
    command->add_flag("--fresnel", options->fresnel,
                      "Whitted mode: split transmission between reflection and refraction by Fresnel's "
                      "equations");
    // bvh8_packet by default: its packets take the primary rays (16 per instruction with AVX-512), and the
    // secondary rays go through bvh8, the fastest single-ray walk (docs/results.md).
    options->accel.name = "bvh8_packet";
    options->accel.add_options(*command);
    command->add_option("--beside", options->beside,
                        "Render the frame again with this structure (e.g. embree, embree16) and print its "
                        "Mrays/s beside the first's");
    options->device.add_options(*command);
    command->add_option("--threads", options->threads, "Threads (0 = all)")->check(CLI::NonNegativeNumber);
    command
        ->add_option("--animate", options->animate,
                     "Render N frames of the scene's meshes deformed by a travelling sine wave (lancer bench "
                     "--animate's), the structure updated between frames; -o names each frame with %d or "
                     "%0Nd (frame_%04d.png)")
        ->check(CLI::Range(1, 100000));
    command
        ->add_option("--instances", options->instances,
                     "Place the scene's meshes (and --with's) N times in all, each built once, at random "
                     "rotations, scales and positions (lancer bench --instances' placements)")
        ->check(CLI::Range(1, 100000000));
    command->add_option("--with", options->with_meshes, "More meshes for --instances to place (repeatable)")
        ->check(CLI::ExistingFile);
    command->callback([options] { run(*options); });
}

}  // namespace lancer::cli
