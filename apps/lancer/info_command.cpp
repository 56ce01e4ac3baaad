// lancer info FILE: what a file holds once loaded, a mesh that a scene graph places several times counted
// once (its objects, instances and the triangles over every placement). lancer info --options: the structures
// and their `--set` keys, from the registry, as the Markdown tables of the README.
#include <fmt/core.h>

#include <memory>
#include <string>
#include <string_view>

#include "commands.hpp"
#include "common.hpp"

namespace lancer::cli {
namespace {

void run(const std::string& file) {
    // The instances as the file places them, so that a mesh placed many times is counted once.
    const LoadedScene loaded = load_timed(file, {.keep_instances = true});
    const Scene& scene = loaded.scene;
    std::size_t vertices = 0, meshes_with_normals = 0;
    for (const TriangleMesh& mesh : scene.meshes) {
        vertices += mesh.positions.size();
        meshes_with_normals += mesh.normals.empty() ? 0 : 1;
    }
    fmt::print("file        {}\n", file);
    fmt::print("load        {:.1f} ms\n", loaded.load_ms);
    fmt::print("meshes      {} ({} with vertex normals)\n", scene.meshes.size(), meshes_with_normals);
    fmt::print("triangles   {}\n", scene.triangle_count());
    fmt::print("vertices    {}\n", vertices);
    if (!scene.instances.empty()) {
        std::size_t object_triangles = 0;
        for (const TriangleMesh& mesh : scene.instanced_meshes)
            object_triangles += mesh.triangle_count();
        fmt::print("objects     {} ({} triangles), meshes placed by instances\n",
                   scene.instanced_meshes.size(), object_triangles);
        fmt::print("instances   {}\n", scene.instances.size());
        fmt::print("instanced   {} triangles over every placement\n", scene.instanced_triangle_count());
    }
    fmt::print("spheres     {}\n", scene.spheres.size());
    fmt::print("planes      {}\n", scene.planes.size());
    fmt::print("materials   {}\n", scene.materials.size());
    fmt::print("lights      {}\n", scene.lights.size());
    const Box3f bounds = scene.bounds();
    if (bounds.empty()) {
        fmt::print("bounds      empty\n");
    } else {
        fmt::print("bounds      ({:g}, {:g}, {:g}) - ({:g}, {:g}, {:g})\n", bounds.lo.x, bounds.lo.y,
                   bounds.lo.z, bounds.hi.x, bounds.hi.y, bounds.hi.z);
    }
    if (scene.camera) {
        const Camera& camera = *scene.camera;
        fmt::print("camera      eye ({:g}, {:g}, {:g}) at ({:g}, {:g}, {:g}) fov {:g} deg, {}x{}\n",
                   camera.eye.x, camera.eye.y, camera.eye.z, camera.look_at.x, camera.look_at.y,
                   camera.look_at.z, camera.vertical_fov_degrees, camera.width, camera.height);
    } else {
        fmt::print("camera      none (renders use the canonical view of shared/bench/VIEWS.md)\n");
    }
}

// A table cell: the pipes escaped, as the README's tables write them.
std::string cell(std::string_view text) {
    std::string escaped;
    for (const char c : text)
        escaped += c == '|' ? std::string("\\|") : std::string(1, c);
    return escaped;
}

void print_options() {
    fmt::print("| `--accel` | structure |\n| --- | --- |\n");
    for (const AccelInfo& accel : accel_infos())
        fmt::print("| `{}` | {} |\n", accel.name, cell(accel.summary));
    fmt::print("\n| `--set` key | accepts | default | sets |\n| --- | --- | --- | --- |\n");
    for (const BuildOptionInfo& option : build_option_infos())
        fmt::print("| `{}` | {} | `{}` | {} |\n", option.key, cell(option.accepted), option.default_value,
                   cell(option.help));
}

}  // namespace

void add_info_command(CLI::App& app) {
    auto file = std::make_shared<std::string>();
    auto options = std::make_shared<bool>(false);
    CLI::App* command = app.add_subcommand(
        "info",
        "Counts, bounds, materials, lights and load time of a file; or the structures and their options");
    CLI::Option* file_option = command->add_option("file", *file, "Mesh or scene file");
    command->add_flag("--options", *options, "List the structures and their --set keys (Markdown)")
        ->excludes(file_option);
    command->callback([file, options] {
        if (*options) {
            print_options();
        } else if (file->empty()) {
            throw InputError("info: give a FILE, or --options");
        } else {
            run(*file);
        }
    });
}

}  // namespace lancer::cli
