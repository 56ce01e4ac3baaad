// A scene ready to trace: the scene, its geometry flattened for the structures, and one acceleration
// structure over that geometry, made together so that they always match. A Pluecker octree file (`.plo`)
// is one more way to make one: its octree is loaded instead of built.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string_view>

#include "lancer/accel.hpp"
#include "lancer/scene.hpp"

namespace lancer {

// A `.plo` file that cannot be read (malformed, truncated, inconsistent, or of another version) or written;
// the message names the file and the first problem.
class StructureFileError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

class World {
  public:
    // Flattens `scene` and builds structure `accel_name` (make_accel's names) on it. Throws
    // std::invalid_argument for an unknown name or a coordinate outside the contract's domain, and
    // std::bad_alloc when the memory limit (lancer/memory_limit.hpp) is passed.
    World(Scene scene, std::string_view accel_name, const BuildOptions& options);

    // The scene and octree of a `.plo` file (written by save_structure): its triangles as one mesh in their
    // stored order, its spheres, the default material; no camera, lights or planes. `triangle_test`
    // replaces the test the file was built with. Throws StructureFileError, std::bad_alloc.
    [[nodiscard]] static World load_structure(const std::filesystem::path& file,
                                              std::optional<TriangleTest> triangle_test = std::nullopt);
    // Writes the structure and its geometry as a `.plo` file; only the `plucker` structure can be written.
    // Throws StructureFileError.
    void save_structure(const std::filesystem::path& file) const;

    [[nodiscard]] const Scene& scene() const { return *scene_; }
    [[nodiscard]] const SceneGeometry& geometry() const { return *geometry_; }
    [[nodiscard]] const Accel& accel() const { return *accel_; }
    [[nodiscard]] const BuildOptions& options() const { return options_; }

  private:
    World() = default;

    // Held by pointer: the structure keeps spans into the geometry, so a World moves without moving them.
    std::unique_ptr<Scene> scene_;
    std::unique_ptr<SceneGeometry> geometry_;
    std::unique_ptr<Accel> accel_;
    BuildOptions options_;
};

}  // namespace lancer
