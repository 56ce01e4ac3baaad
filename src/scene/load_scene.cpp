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

// The invariants scene.hpp promises to every consumer, checked once here whatever the format: a reader bug
// or a file that slipped past assimp's checks becomes a LoadError, not a wild read at render time.
constexpr const char* kDomain = "[-2^60, 2^60]";

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
        // Finite values can still overflow on the way (a huge cone radius); the structures take coordinates
        // within the contract's domain (kCoordinateLimit, docs/numerical-contract.md).
        for (const Vec3f& position : mesh.positions) {
            if (!in_coordinate_domain(position))
                fail(name + " has a vertex outside the coordinate domain " + kDomain);
        }
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
        for (std::size_t t = 0; t < mesh.material_ids.size(); ++t) {
            // The message is built only for the culprit: this loop runs over every triangle.
            if (mesh.material_ids[t] >= material_count) {
                check_material(mesh.material_ids[t], "triangle " + std::to_string(t) + " of " + name);
            }
        }
    }
    for (const Sphere& sphere : scene.spheres) {
        check_material(sphere.material, "a sphere");
        const Box3f bounds = sphere.bounds();
        if (!in_coordinate_domain(bounds.lo) || !in_coordinate_domain(bounds.hi))
            fail("a sphere reaches outside the coordinate domain " + std::string(kDomain));
    }
}

}  // namespace

Scene load_scene(const std::filesystem::path& file) {
    const std::string extension = lower_case_extension(file);
    Scene scene = extension == ".off"                          ? load_off(file)
                  : extension == ".dsc"                        ? load_dsc(file)
                  : extension == ".nff"                        ? load_nff(file)
                  : extension == ".ply" || has_ply_magic(file) ? load_ply(file)
                                                               : load_with_assimp(file);
    if (scene.materials.empty()) scene.materials.emplace_back();
    for (TriangleMesh& mesh : scene.meshes)
        fold_uniform_materials(mesh);
    check_scene(scene, file);
    return scene;
}

}  // namespace lancer
