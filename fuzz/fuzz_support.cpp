#include "fuzz_support.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <string>
#include <system_error>

#include "lancer/load_scene.hpp"

namespace lancer::fuzz {

namespace fs = std::filesystem;

void finding(std::string_view what) {
    std::fprintf(stderr, "lancer fuzz finding: %.*s\n", static_cast<int>(what.size()), what.data());
    std::abort();
}

namespace {

fs::path make_scratch_dir() {
    std::string pattern = (fs::temp_directory_path() / "lancer-fuzz-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) finding("cannot create a scratch folder under $TMPDIR");
    return pattern;
}

}  // namespace

const fs::path& scratch_dir() {
    static const fs::path dir = [] {
        fs::path made = make_scratch_dir();
        std::atexit([] {
            std::error_code ignored;
            fs::remove_all(scratch_dir(), ignored);
        });
        return made;
    }();
    return dir;
}

fs::path write_scratch_file(std::string_view name, std::string_view bytes) {
    const fs::path file = scratch_dir() / name;
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) finding("cannot write a scratch file");
    return file;
}

void check_scene_contract(const Scene& scene) {
    if (scene.materials.empty()) finding("a loaded scene has no material");
    const std::size_t material_count = scene.materials.size();
    for (const TriangleMesh& mesh : scene.meshes) {
        for (const Vec3f& position : mesh.positions) {
            if (!in_coordinate_domain(position)) finding("a loaded vertex is outside the coordinate domain");
        }
        if (mesh.indices.size() % 3 != 0) finding("a loaded mesh has an index count not a multiple of 3");
        for (const std::uint32_t index : mesh.indices) {
            if (index >= mesh.positions.size()) finding("a loaded vertex index is out of range");
        }
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
            finding("a loaded mesh has normals, but not one per vertex");
        if (!mesh.material_ids.empty() && mesh.material_ids.size() != mesh.triangle_count())
            finding("a loaded mesh has material ids, but not one per triangle");
        if (mesh.material >= material_count) finding("a loaded mesh's material is out of range");
        for (const std::uint32_t material : mesh.material_ids) {
            if (material >= material_count) finding("a loaded triangle's material is out of range");
        }
    }
    for (const Sphere& sphere : scene.spheres) {
        if (sphere.material >= material_count) finding("a loaded sphere's material is out of range");
        const Box3f bounds = sphere.bounds();
        if (!in_coordinate_domain(bounds.lo) || !in_coordinate_domain(bounds.hi) || !(sphere.radius > 0.0f))
            finding("a loaded sphere is outside the coordinate domain or has no positive radius");
    }
    for (const Plane& plane : scene.planes) {
        if (plane.material >= material_count) finding("a loaded plane's material is out of range");
        if (!is_finite(plane.normal) || !std::isfinite(plane.offset)) finding("a loaded plane is not finite");
    }
}

void load_and_check(const fs::path& file) {
    try {
        check_scene_contract(load_scene(file));
    } catch (const LoadError&) {
        // The other half of the contract: bad input is a LoadError.
    } catch (const std::exception& error) {
        finding(std::string("load_scene threw something other than LoadError: ") + error.what());
    }
}

}  // namespace lancer::fuzz
