// DSC, Ferreira & Mendoza 2011, section 5.2: the materials, lights and image size that go with the .off of
// the same stem.
//   DSC
//   width height
//   nmaterials nlights
//   r g b reflection intensity refraction_index      nmaterials lines
//   x y z r g b                                      nlights lines
//   ntriangles                                       equal to the .off's face count
//   material                                         ntriangles lines, 0-based, one per .off face
// '#' comments are allowed as in OFF. A polygon face's fan triangles share its material.
#include <algorithm>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene/loaders.hpp"
#include "scene/text_reader.hpp"

namespace lancer {

namespace {

// The fewest characters of a record, line break included ("0 0 0 0 0 0\n", "0\n").
constexpr std::size_t min_material_chars = 12;
constexpr std::size_t min_light_chars = 12;
constexpr std::size_t min_triangle_chars = 2;

// Ferreira & Mendoza 2011 name three coefficients; Whitted's model has four weights. The transmission weight
// is what the diffuse and reflection weights leave, and only a refracting material (index set and not 1) has
// one.
Material dsc_material(Vec3f color, float reflection, float intensity, float refraction_index) {
    Material material;
    material.color = color;
    material.ks = reflection;
    material.kd = intensity;
    material.ior = refraction_index;
    const bool refracts = refraction_index > 0.0f && refraction_index != 1.0f;
    material.kt = refracts ? std::max(0.0f, 1.0f - material.kd - material.ks) : 0.0f;
    material.two_sided = material.kt > 0.0f;
    return material;
}

}  // namespace

Scene load_dsc(const std::filesystem::path& file) {
    TextReader reader(file);
    reader.expect_keyword("DSC");
    const int width = reader.read_image_side("an image width");
    const int height = reader.read_image_side("an image height");
    Token material_count_token, light_count_token;
    const std::uint64_t material_count = reader.read_count("a material count", &material_count_token);
    const std::uint64_t light_count = reader.read_count("a light count", &light_count_token);
    const std::size_t budget = reader.byte_budget();
    reader.check_fits(material_count, min_material_chars, budget, material_count_token, "materials");
    reader.check_fits(light_count, min_light_chars, budget - material_count * min_material_chars,
                      light_count_token, "lights");

    Scene scene;
    scene.materials.reserve(material_count);
    for (std::uint64_t i = 0; i < material_count; ++i) {
        if (!reader.peek()) reader.fail_at_end(count_message(material_count, "materials", i));
        const Vec3f color = reader.read_vec3("a material colour r g b");
        const float reflection = reader.read_float("a reflection coefficient");
        const float intensity = reader.read_float("an intensity coefficient");
        const float refraction_index = reader.read_float("a refraction index");
        scene.materials.push_back(dsc_material(color, reflection, intensity, refraction_index));
    }
    scene.lights.reserve(light_count);
    for (std::uint64_t i = 0; i < light_count; ++i) {
        if (!reader.peek()) reader.fail_at_end(count_message(light_count, "lights", i));
        Light light;
        light.position = reader.read_vec3("a light position x y z");
        light.color = reader.read_vec3("a light colour r g b");
        scene.lights.push_back(light);
    }

    Token triangle_count_token;
    const std::uint64_t triangle_count = reader.read_count("a triangle count", &triangle_count_token);
    reader.check_fits(triangle_count, min_triangle_chars, reader.byte_budget(), triangle_count_token,
                      "triangle materials");
    std::vector<std::uint32_t> face_materials;
    face_materials.reserve(triangle_count);
    for (std::uint64_t i = 0; i < triangle_count; ++i) {
        if (!reader.peek()) reader.fail_at_end(count_message(triangle_count, "triangle materials", i));
        Token token;
        const std::int64_t material = reader.read_integer("a material index", &token);
        if (material < 0 || static_cast<std::uint64_t>(material) >= material_count) {
            reader.fail(token.line, "material index " + std::to_string(material) + " out of range [0, " +
                                        std::to_string(material_count) + ")");
        }
        face_materials.push_back(static_cast<std::uint32_t>(material));
    }
    if (const std::optional<Token> extra = reader.next()) {
        reader.fail(extra->line, "expected the end of the file after " + std::to_string(triangle_count) +
                                     " triangle materials, got " + quote_token(extra->text));
    }

    std::filesystem::path off_file = file;
    off_file.replace_extension(".off");
    if (!std::filesystem::exists(off_file)) {
        throw LoadError(
            file, 0, "cannot find the mesh " + off_file.string() + " that this scene description goes with");
    }
    OffMesh off = read_off(off_file);
    if (off.face_count != triangle_count) {
        reader.fail(triangle_count_token.line, "triangle count " + std::to_string(triangle_count) +
                                                   " does not match the " + std::to_string(off.face_count) +
                                                   " faces of " + off_file.filename().string());
    }
    TriangleMesh& mesh = off.mesh;
    mesh.material_ids.reserve(mesh.triangle_count());
    for (const std::uint32_t face : off.face_of_triangle)
        mesh.material_ids.push_back(face_materials[face]);

    // VIEWS.md frames the box over all the vertices of the file, used or not.
    Box3f bounds;
    for (const Vec3f& position : mesh.positions)
        bounds.extend(position);
    if (!bounds.empty()) scene.camera = canonical_view(bounds, width, height);
    scene.meshes.push_back(std::move(mesh));
    return scene;
}

}  // namespace lancer
