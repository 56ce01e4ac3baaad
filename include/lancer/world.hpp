// A scene ready to trace: the scene, its geometry flattened for the structures, and one acceleration
// structure over that geometry, made together so that they always match. A Plücker octree file (`.plo`)
// is one more way to make one: its octree is loaded instead of built.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string_view>

#include "lancer/accel.hpp"
#include "lancer/instances.hpp"
#include "lancer/scene.hpp"

namespace lancer {

// A `.plo` file that cannot be read (malformed, truncated, inconsistent, or of another version) or written;
// the message names the file and the first problem.
class StructureFileError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// New positions for the vertices of one mesh of a World's scene: as many as the mesh has, in its order.
struct MeshVertices {
    std::size_t mesh = 0;
    std::span<const Vec3f> positions;
};

class World {
  public:
    // Flattens `scene` and builds structure `accel_name` (make_accel's names) on it; the world keeps a copy
    // of the scene, or takes a scene moved in once the build has succeeded, which spares a large mesh the
    // copy's page faults (docs/python.md, "Building"). Throws std::invalid_argument for an unknown name or
    // a coordinate outside the contract's domain, and std::bad_alloc when the memory limit
    // (lancer/memory_limit.hpp) is passed; a scene moved in is then left as it was.
    World(const Scene& scene, std::string_view accel_name, const BuildOptions& options);
    World(Scene&& scene, std::string_view accel_name, const BuildOptions& options);

    // The scene and octree of a `.plo` file (written by save_structure): its triangles as one mesh in their
    // stored order, its spheres, the default material; no camera, lights or planes. `triangle_test`
    // replaces the test the file was built with. Throws StructureFileError, std::bad_alloc.
    [[nodiscard]] static World load_structure(const std::filesystem::path& file,
                                              std::optional<TriangleTest> triangle_test = std::nullopt);
    // Writes the structure and its geometry as a `.plo` file; only the Plücker octree (`plucker`,
    // `plucker_packet`) can be written.
    // Throws StructureFileError.
    void save_structure(const std::filesystem::path& file) const;

    // Moves the vertices of the meshes named in `moves` (their connectivity stays) and updates the structure
    // once for all of them (Accel::update: the BVHs refit, the others rebuild). A mesh with vertex normals
    // gets them recomputed from its moved triangles (area-weighted). Throws std::invalid_argument
    // naming the first problem, the world left as it was: a mesh index out of range or named twice, another
    // vertex count, a coordinate that is NaN, infinite or outside the contract's domain.
    UpdateReport update_vertices(std::span<const MeshVertices> moves);
    UpdateReport update_vertices(std::size_t mesh, std::span<const Vec3f> positions) {
        const MeshVertices move{mesh, positions};
        return update_vertices(std::span(&move, 1));
    }

    [[nodiscard]] const Scene& scene() const { return *scene_; }
    // The scene moved out, for a caller that changes it and builds a new World (a Python scene given more
    // triangles); the world keeps nothing and is only to be destroyed.
    [[nodiscard]] Scene take_scene() &&;
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

// A World for a scene whose meshes are placed by instances (Scene::instances: load_scene's keep_instances):
// each instanced mesh built once as structure `accel_name`, the scene's other meshes and spheres as a World's
// geometry and structure placed once by the identity, under an InstancedScene's top level
// (docs/accel/instances.md). Object k and instance i are the scene's instanced mesh k and instance i; the
// rest, when the scene has meshes or spheres, is the last object, placed by the last instance.
class InstancedWorld {
  public:
    // Throws std::invalid_argument for a scene check_scene refuses, an unknown structure, or an instance
    // whose transform the InstancedScene refuses (naming it), and std::bad_alloc past the memory limit.
    InstancedWorld(Scene scene, std::string_view accel_name, const BuildOptions& options);

    [[nodiscard]] const Scene& scene() const { return *scene_; }
    // The meshes and spheres outside the instances, flattened as a World's.
    [[nodiscard]] const SceneGeometry& geometry() const { return *geometry_; }
    [[nodiscard]] const InstancedScene& instanced() const { return *instanced_; }
    // The object that holds geometry(), or -1 when it is empty.
    [[nodiscard]] std::int32_t rest_object() const { return rest_object_; }
    // Milliseconds to build the objects' structures and the top level.
    [[nodiscard]] double build_ms() const { return build_ms_; }

  private:
    std::unique_ptr<Scene> scene_;
    std::unique_ptr<SceneGeometry> geometry_;
    std::unique_ptr<Accel> rest_;  // over geometry(); null when it is empty
    std::unique_ptr<InstancedScene> instanced_;
    std::int32_t rest_object_ = -1;
    double build_ms_ = 0.0;
};

}  // namespace lancer
