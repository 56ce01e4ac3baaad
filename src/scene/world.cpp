#include "lancer/world.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "accel/plucker/plucker.hpp"
#include "accel/plucker/serialise.hpp"
#include "core/checked_points.hpp"
#include "core/parallel.hpp"

namespace lancer {

World::World(const Scene& scene, std::string_view accel_name, const BuildOptions& options)
    : World(Scene(scene), accel_name, options) {}

World::World(Scene&& scene, std::string_view accel_name, const BuildOptions& options)
    : accel_(make_accel(accel_name)), options_(options) {
    // Its structure is one over the scene's meshes: the instances' meshes would be left out unseen.
    if (!scene.instances.empty()) {
        throw std::invalid_argument("World: the scene places meshes by " +
                                    std::to_string(scene.instances.size()) +
                                    " instances, which a World does not trace (lancer::InstancedScene does; "
                                    "load_scene without keep_instances makes each placement a mesh)");
    }
    // The flattened geometry holds no reference to the scene, so the scene is taken only once the build has
    // succeeded: a build that throws leaves the caller's scene as it was.
    geometry_ = std::make_unique<SceneGeometry>(scene);
    accel_->build(geometry_->view(), options_);
    scene_ = std::make_unique<Scene>(std::move(scene));
}

Scene World::take_scene() && {
    Scene scene = std::move(*scene_);
    scene_.reset();
    geometry_.reset();
    accel_.reset();
    return scene;
}

namespace {

// Vertices per task of the checks and copies of update_vertices: every frame of an animation makes them.
constexpr std::size_t kVertexGrain = 1 << 15;

// A moved mesh's vertex normals: the sum of its triangles' normals around each vertex, weighted by their
// areas (the cross products' lengths), made unit; a vertex whose sum is zero keeps its old normal.
void recompute_normals(TriangleMesh& mesh) {
    std::vector<Vec3f> sums(mesh.positions.size(), Vec3f(0.0f));
    for (std::size_t i = 0; i < mesh.triangle_count(); ++i) {
        const Vec3f normal = mesh.triangle(i).geometric_normal();
        for (int corner = 0; corner < 3; ++corner)
            sums[mesh.indices[3 * i + static_cast<std::size_t>(corner)]] += normal;
    }
    for (std::size_t v = 0; v < sums.size(); ++v) {
        const float norm = length(sums[v]);
        if (norm > 0.0f && std::isfinite(norm)) mesh.normals[v] = sums[v] / norm;
    }
}

}  // namespace

UpdateReport World::update_vertices(std::span<const MeshVertices> moves) {
    const auto start = std::chrono::steady_clock::now();
    std::vector<bool> named(scene_->meshes.size(), false);
    std::vector<Box3f> positions_boxes;
    positions_boxes.reserve(moves.size());
    for (const MeshVertices& move : moves) {
        if (move.mesh >= scene_->meshes.size()) {
            throw std::invalid_argument("update_vertices: mesh " + std::to_string(move.mesh) +
                                        ", the scene has " + std::to_string(scene_->meshes.size()));
        }
        if (named[move.mesh])
            throw std::invalid_argument("update_vertices: mesh " + std::to_string(move.mesh) +
                                        " named twice");
        named[move.mesh] = true;
        const TriangleMesh& mesh = scene_->meshes[move.mesh];
        if (move.positions.size() != mesh.positions.size()) {
            throw std::invalid_argument("update_vertices: " + std::to_string(move.positions.size()) +
                                        " positions for mesh " + std::to_string(move.mesh) + ", which has " +
                                        std::to_string(mesh.positions.size()) + " vertices");
        }
        static_assert(sizeof(Vec3f) == 3 * sizeof(float) && std::is_standard_layout_v<Vec3f>);
        const CheckedPoints checked = check_points(
            {reinterpret_cast<const float*>(move.positions.data()), 3 * move.positions.size()}, 1);
        if (checked.first_outside != CheckedPoints::kNone) {
            throw std::invalid_argument("update_vertices: vertex " + std::to_string(checked.first_outside) +
                                        " of mesh " + std::to_string(move.mesh) +
                                        " is NaN, infinite or outside the coordinate domain [-2^60, 2^60]");
        }
        positions_boxes.push_back(checked.box);
    }
    for (std::size_t m = 0; m < moves.size(); ++m) {
        const MeshVertices& move = moves[m];
        TriangleMesh& mesh = scene_->meshes[move.mesh];
        parallel::for_each_chunk(0, move.positions.size(), kVertexGrain,
                                 [&](std::size_t from, std::size_t to) {
                                     std::copy(move.positions.begin() + static_cast<std::ptrdiff_t>(from),
                                               move.positions.begin() + static_cast<std::ptrdiff_t>(to),
                                               mesh.positions.begin() + static_cast<std::ptrdiff_t>(from));
                                 });
        if (!mesh.normals.empty()) recompute_normals(mesh);
        geometry_->refresh_mesh(move.mesh, mesh, positions_boxes[m]);
    }
    // The positions were checked above, and the flattening took the box: the structure need not read every
    // triangle again to check it (Accel::update_within).
    UpdateReport report = accel_->update_within(geometry_->view(), geometry_->hit_bounds());
    report.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return report;
}

namespace {

// The scene a `.plo` file stands for (World::load_structure).
Scene scene_of(const plucker::PluckerFile& file) {
    Scene scene;
    TriangleMesh mesh;
    mesh.name = "plucker";
    mesh.positions.reserve(3 * file.triangles.size());
    mesh.indices.reserve(3 * file.triangles.size());
    for (const Triangle& triangle : file.triangles) {
        for (const Vec3f& vertex : {triangle.v0, triangle.v1, triangle.v2}) {
            mesh.indices.push_back(static_cast<std::uint32_t>(mesh.positions.size()));
            mesh.positions.push_back(vertex);
        }
    }
    scene.meshes.push_back(std::move(mesh));
    scene.spheres = file.spheres;
    for (Sphere& sphere : scene.spheres)
        sphere.material = 0;
    scene.materials.emplace_back();
    return scene;
}

}  // namespace

World World::load_structure(const std::filesystem::path& file, std::optional<TriangleTest> triangle_test) {
    plucker::PluckerFile stored = plucker::read_plucker_file(file);
    World world;
    world.scene_ = std::make_unique<Scene>(scene_of(stored));
    world.geometry_ = std::make_unique<SceneGeometry>(*world.scene_);
    world.options_ = build_options(triangle_test.value_or(stored.triangle_test));
    // The layout's own variant, which the file fixed when it was written.
    PluckerOptions& plucker_options = world.options_.group<PluckerOptions>();
    plucker_options.balanced = stored.layout.options.balanced;
    plucker_options.stored_boxes = stored.layout.options.stored_boxes;
    plucker_options.morton = stored.layout.options.morton;
    auto accel = std::make_unique<PluckerAccel>();
    accel->adopt(world.geometry_->view(), world.options_, std::move(stored.layout));
    world.accel_ = std::move(accel);
    return world;
}

void World::save_structure(const std::filesystem::path& file) const {
    const plucker::PluckerLayout* layout = accel_->exported_layout().plucker;
    if (layout == nullptr) {
        const std::string accel_name(accel_->name());
        throw StructureFileError(file.string() + ": only the plucker structures (plucker, plucker_packet) " +
                                 "can be saved (this world's is " + accel_name + ")");
    }
    plucker::write_plucker_file(file, geometry_->view(), *layout, options_.triangle_test);
}

}  // namespace lancer
