#include <algorithm>
#include <cctype>
#include <fstream>
#include <string>
#include <string_view>

#include "lancer/load_scene.hpp"
#include "scene/loaders.hpp"

namespace lancer {

namespace {

std::string lower_case_extension(const std::filesystem::path& file) {
    std::string extension = file.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return extension;
}

// assimp would take a file that starts with the PLY magic for PLY whatever its name; the PLY reader here is
// the robust one.
bool has_ply_magic(const std::filesystem::path& file) {
    char magic[4] = {};
    std::ifstream(file, std::ios::binary).read(magic, sizeof magic);
    return std::string_view(magic, 3) == "ply" && (magic[3] == '\n' || magic[3] == '\r');
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

}  // namespace

Scene load_scene(const std::filesystem::path& file, const LoadOptions& options) {
    const std::string extension = lower_case_extension(file);
    Scene scene = extension == ".off"   ? load_off(file)
                  : extension == ".dsc" ? load_dsc(file)
                  : extension == ".nff" ? load_nff(file)
                  : extension == ".ply" || has_ply_magic(file)
                      ? load_ply(file)
                      : load_with_assimp(file, options.keep_instances);
    if (scene.materials.empty()) scene.materials.emplace_back();
    for (TriangleMesh& mesh : scene.meshes)
        fold_uniform_materials(mesh);
    for (TriangleMesh& mesh : scene.instanced_meshes)
        fold_uniform_materials(mesh);
    // The invariants scene.hpp promises, checked once here whatever the format: a reader bug or a file that
    // slipped past assimp's checks becomes a LoadError, not a wild read at render time.
    try {
        check_scene(scene);
    } catch (const std::invalid_argument& error) {
        throw LoadError(file, 0, error.what());
    }
    return scene;
}

}  // namespace lancer
