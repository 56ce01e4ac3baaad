// Scene and mesh loaders. Bad input never crashes: it throws LoadError naming the file, the line and what
// was expected; the CLI turns that into a message on stderr and exit code 2.
#pragma once

#include <cstddef>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "lancer/scene.hpp"

namespace lancer {

class LoadError : public std::runtime_error {
  public:
    // line = 0 when the error is not tied to a line (missing file, binary formats).
    LoadError(std::filesystem::path file, std::size_t line, const std::string& message);

    [[nodiscard]] const std::filesystem::path& file() const { return file_; }
    [[nodiscard]] std::size_t line() const { return line_; }

  private:
    std::filesystem::path file_;
    std::size_t line_;
};

struct LoadOptions {
    // A mesh that several nodes of a scene graph place (glTF's node hierarchy, Collada's instance nodes,
    // through assimp) becomes one Scene::instanced_meshes entry in its own frame and a MeshInstance per
    // placement, for lancer::InstancedScene to build once. Off: each placement is a mesh of its own, moved
    // by its node, as a World takes them. A placement whose transform cannot be inverted (singular, not
    // affine) makes its mesh's placements meshes of their own either way.
    bool keep_instances = false;
};

// Loads by extension: .off (polygons fan-triangulated, file order kept), .dsc (Ferreira & Mendoza 2011: reads
// the .off of the same stem beside it), .nff (Haines' SPD), anything else through assimp (PLY, OBJ, STL,
// glTF, ...). The scene always has at least one material; a scene without camera keeps camera empty.
[[nodiscard]] Scene load_scene(const std::filesystem::path& file, const LoadOptions& options = {});

}  // namespace lancer
