// The readers behind load_scene (include/lancer/load_scene.hpp), one per format. Each returns the scene as
// the file describes it; load_scene then adds the default material and checks the scene's invariants.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "lancer/scene.hpp"

namespace lancer {

// An OFF file: one mesh named after the file stem, its polygons fan-triangulated (i0, ik, ik+1) with the
// triangles numbered in file order (an external contract: `lancer rays` reports these numbers).
struct OffMesh {
    TriangleMesh mesh;
    std::size_t face_count = 0;
    std::vector<std::uint32_t> face_of_triangle;  // the face each triangle comes from, one per triangle
};

[[nodiscard]] OffMesh read_off(const std::filesystem::path& file);

[[nodiscard]] Scene load_off(const std::filesystem::path& file);
// Ferreira & Mendoza's scene description (2011, section 5.2): materials, lights and a per-face material for
// the .off of the same stem.
[[nodiscard]] Scene load_dsc(const std::filesystem::path& file);
// Eric Haines' Neutral File Format, as the Standard Procedural Databases write it.
[[nodiscard]] Scene load_nff(const std::filesystem::path& file);
// PLY, ascii or binary.
[[nodiscard]] Scene load_ply(const std::filesystem::path& file);
// OBJ, STL, glTF, Collada and the other formats assimp reads; with `keep_instances`, the meshes that several
// nodes place as Scene::instances (LoadOptions).
[[nodiscard]] Scene load_with_assimp(const std::filesystem::path& file, bool keep_instances);

}  // namespace lancer
