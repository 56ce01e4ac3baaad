#include <algorithm>
#include <cctype>
#include <string>

#include "lancer/io.hpp"
#include "scene/loaders.hpp"

namespace lancer {

namespace {

std::string lower_case_extension(const std::filesystem::path& file) {
    std::string extension = file.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return extension;
}

// One material id per triangle where one would do costs memory and a lookup per hit.
void fold_uniform_materials(TriangleMesh& mesh) {
    if (mesh.material_ids.empty()) return;
    const std::uint32_t first = mesh.material_ids.front();
    if (std::all_of(mesh.material_ids.begin(), mesh.material_ids.end(),
                    [&](std::uint32_t id) { return id == first; })) {
        mesh.material = first;
        mesh.material_ids.clear();
    }
}

// The invariants scene.hpp promises to every consumer, checked once here whatever the format: a reader bug
// or a file that slipped past assimp's checks becomes a LoadError, not a wild read at render time.
void check_scene(const Scene& scene, const std::filesystem::path& file) {
    const auto fail = [&](const std::string& message) { throw LoadError(file, 0, message); };
    const std::size_t material_count = scene.materials.size();
    const auto check_material = [&](std::uint32_t material, const std::string& user) {
        if (material >= material_count) {
            fail(user + " uses material " + std::to_string(material) + ", but the scene has " +
                 std::to_string(material_count));
        }
    };
    for (const TriangleMesh& mesh : scene.meshes) {
        const std::string name = "mesh '" + mesh.name + "'";
        if (mesh.indices.size() % 3 != 0) fail(name + " has an index count that is not a multiple of 3");
        for (const std::uint32_t index : mesh.indices) {
            if (index >= mesh.positions.size()) fail(name + " has a vertex index out of range");
        }
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) {
            fail(name + " has " + std::to_string(mesh.normals.size()) + " normals for " +
                 std::to_string(mesh.positions.size()) + " vertices");
        }
        if (!mesh.material_ids.empty() && mesh.material_ids.size() != mesh.triangle_count()) {
            fail(name + " has " + std::to_string(mesh.material_ids.size()) + " material ids for " +
                 std::to_string(mesh.triangle_count()) + " triangles");
        }
        check_material(mesh.material, name);
        for (const std::uint32_t material : mesh.material_ids)
            check_material(material, "a triangle of " + name);
    }
    for (const Sphere& sphere : scene.spheres)
        check_material(sphere.material, "a sphere");
}

}  // namespace

Scene load_scene(const std::filesystem::path& file) {
    const std::string extension = lower_case_extension(file);
    Scene scene = extension == ".off"   ? load_off(file)
                  : extension == ".dsc" ? load_dsc(file)
                  : extension == ".nff" ? load_nff(file)
                                        : load_with_assimp(file);
    if (scene.materials.empty()) scene.materials.emplace_back();
    for (TriangleMesh& mesh : scene.meshes)
        fold_uniform_materials(mesh);
    check_scene(scene, file);
    return scene;
}

}  // namespace lancer
