#include <chrono>
#include <stdexcept>
#include <string>

#include "lancer/world.hpp"

namespace lancer {

InstancedWorld::InstancedWorld(Scene scene, std::string_view accel_name, const BuildOptions& options)
    : scene_(std::make_unique<Scene>(std::move(scene))),
      geometry_(std::make_unique<SceneGeometry>(*scene_)),
      instanced_(std::make_unique<InstancedScene>(options)) {
    check_scene(*scene_);
    const auto start = std::chrono::steady_clock::now();
    for (const TriangleMesh& mesh : scene_->instanced_meshes)
        static_cast<void>(instanced_->add_object(mesh, accel_name, options));
    for (const MeshInstance& instance : scene_->instances)
        static_cast<void>(instanced_->add_instance(instance.mesh, instance.object_to_world));
    if (geometry_->view().size() > 0) {
        rest_ = make_accel(accel_name);
        rest_->build(geometry_->view(), options);
        // The rest's structure lives as long as the world: the object holds it without owning it.
        rest_object_ = static_cast<std::int32_t>(instanced_->add_object(
            std::shared_ptr<const Accel>(std::shared_ptr<const Accel>(), rest_.get())));
        static_cast<void>(instanced_->add_instance(static_cast<std::uint32_t>(rest_object_), Transform{}));
    }
    static_cast<void>(instanced_->commit());
    build_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace lancer
