// The scene: triangle meshes, spheres, infinite planes, materials, lights and a camera, as the loaders fill
// it.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "lancer/box.hpp"
#include "lancer/huge_pages.hpp"
#include "lancer/transform.hpp"
#include "lancer/vec.hpp"

namespace lancer {

// 36 bytes: the three vertices in file order (the hit's barycentrics refer to this order).
struct Triangle {
    Vec3f v0, v1, v2;

    [[nodiscard]] Box3f bounds() const {
        Box3f box;
        box.extend(v0), box.extend(v1), box.extend(v2);
        return box;
    }
    // Right-handed, not normalised: (v1 - v0) x (v2 - v0).
    [[nodiscard]] Vec3f geometric_normal() const { return cross(v1 - v0, v2 - v0); }
};

struct Sphere {
    Vec3f center;
    float radius = 1.0f;
    std::uint32_t material = 0;

    [[nodiscard]] Box3f bounds() const { return {center - Vec3f(radius), center + Vec3f(radius)}; }
};

// The plane x . normal = offset with a unit normal (the "Lancer de rayon" slides, "intersection rayon-plan").
// Planes are unbounded, so no acceleration structure holds them: the scene tests them one by one.
struct Plane {
    Vec3f normal{0.0f, 1.0f, 0.0f};
    float offset = 0.0f;
    std::uint32_t material = 0;
    bool checkered = false;  // alternate the material's colour with its darkened copy on a unit grid
};

// One surface description that covers the seed-003 .dsc material and the NFF `f` line.
// Whitted's model (Ferreira & Mendoza 2011, 4.3): I = Ia + kd sum(N.L) + ks S + kt T.
struct Material {
    Vec3f color{0.8f};
    float kd = 1.0f;         // diffuse weight
    float ks = 0.0f;         // specular weight: mirror ray and highlight
    float shininess = 0.0f;  // Phong exponent, 0 = no highlight
    float kt = 0.0f;         // transmission weight
    float ior = 1.0f;        // index of refraction
    bool two_sided = false;  // NFF: transmissive surfaces have two sides
};

struct Light {
    Vec3f position;
    Vec3f color{1.0f};
};

// The pinhole camera of the "Lancer de rayon" slides and of shared/bench/VIEWS.md.
struct Camera {
    Vec3f eye;
    Vec3f look_at;
    Vec3f up{0.0f, 1.0f, 0.0f};
    float vertical_fov_degrees = 45.0f;  // full angle between the top and bottom film edges
    int width = 1024;
    int height = 1024;
};

struct TriangleMesh {
    std::string name;
    std::vector<Vec3f> positions;
    std::vector<std::uint32_t> indices;       // three per triangle, each < positions.size()
    std::vector<Vec3f> normals;               // empty, or one per position (smooth shading)
    std::vector<std::uint32_t> material_ids;  // empty (every triangle uses `material`), or one per triangle
    std::uint32_t material = 0;

    [[nodiscard]] std::size_t triangle_count() const { return indices.size() / 3; }
    // Room for `vertex_count` positions and `triangle_count` triangles' indices, asked in transparent huge
    // pages: filling it then faults once per 2 MiB instead of once per 4 KiB (docs/python.md, "Building").
    void reserve(std::size_t vertex_count, std::size_t triangle_count);
    [[nodiscard]] Triangle triangle(std::size_t i) const {
        return {positions[indices[3 * i]], positions[indices[3 * i + 1]], positions[indices[3 * i + 2]]};
    }
    [[nodiscard]] std::uint32_t material_of(std::size_t i) const {
        return material_ids.empty() ? material : material_ids[i];
    }
    // The indexed mesh flattened into the triangle array the structures are built over (Geometry), in
    // triangle order: appended to `out`, or returned. append_triangles does not reserve: an exact reserve
    // per call would reallocate on every mesh appended to one array (reserve the total first).
    void append_triangles(std::vector<Triangle>& out) const {
        for (std::size_t i = 0; i < triangle_count(); ++i)
            out.push_back(triangle(i));
    }
    [[nodiscard]] std::vector<Triangle> triangles() const {
        std::vector<Triangle> out;
        out.reserve(triangle_count());
        append_triangles(out);
        return out;
    }
};

// What an acceleration structure is built over. Global primitive numbering: triangles first, in mesh order
// then file order, [0, T); then spheres, [T, T + S). The spans must outlive the structure built on them.
// The coordinate domain of the numerical contract: every coordinate of a triangle vertex, and of the box of a
// sphere that can be hit (radius > 0), lies in [-2^60, 2^60]. Intel Embree documents the same range for its
// geometry (FLT_LARGE = 1.8e18), and the octrees' root cube (lo plus a power-of-two size) stays finite in it.
// load_scene rejects a scene beyond it with a LoadError, Accel::build with std::invalid_argument.
inline constexpr float kCoordinateLimit = 0x1p60f;
[[nodiscard]] inline bool in_coordinate_domain(Vec3f p) {
    // Written so that NaN fails.
    return std::fabs(p.x) <= kCoordinateLimit && std::fabs(p.y) <= kCoordinateLimit &&
           std::fabs(p.z) <= kCoordinateLimit;
}

struct Geometry {
    std::span<const Triangle> triangles;
    std::span<const Sphere> spheres;

    [[nodiscard]] std::size_t size() const { return triangles.size() + spheres.size(); }
    [[nodiscard]] Box3f bounds() const;
};

// A placement of a mesh that a scene graph places several times (glTF's node hierarchy): mesh `mesh` of
// Scene::instanced_meshes, moved to the world by `object_to_world`.
struct MeshInstance {
    std::uint32_t mesh = 0;
    Transform object_to_world;
};

struct Scene {
    std::vector<TriangleMesh> meshes;
    // Meshes that several nodes of a scene graph place, each in its own frame and placed by `instances`
    // only (load_scene's LoadOptions::keep_instances; empty otherwise, every placement then a mesh of
    // `meshes`). A World refuses them; lancer::InstancedScene builds each once.
    std::vector<TriangleMesh> instanced_meshes;
    std::vector<MeshInstance> instances;
    std::vector<Sphere> spheres;
    std::vector<Plane> planes;
    std::vector<Material> materials;  // indexed by the primitives' material ids; never empty after loading
    std::vector<Light> lights;
    std::optional<Camera> camera;
    Vec3f background{0.0f};
    Vec3f ambient{0.1f};

    // The triangles of `meshes`, the ones a World holds.
    [[nodiscard]] std::size_t triangle_count() const;
    // Over every placement: triangle_count() and each instance's mesh's triangles, what the scene flattened
    // would hold.
    [[nodiscard]] std::size_t instanced_triangle_count() const;
    // Bounds of the bounded primitives (meshes, spheres, and each instance's mesh's box moved to the world);
    // planes are infinite.
    [[nodiscard]] Box3f bounds() const;
};

// Checks what every consumer of a Scene relies on: vertices and spheres inside the coordinate domain,
// indices in range and in threes, one normal per vertex and one material id per triangle where given, every
// material id in range, fewer primitives than a hit's 32-bit id numbers; the same of each instanced mesh,
// and each instance naming one with a finite transform. Throws std::invalid_argument
// naming the first broken one. load_scene and the renderer call it; a scene made in code may too.
void check_scene(const Scene& scene);

// The scene flattened for the structures: one triangle array, the spheres, and the way back from a global
// triangle index to its mesh. Built once after loading.
class SceneGeometry {
  public:
    explicit SceneGeometry(const Scene& scene);

    [[nodiscard]] Geometry view() const { return {triangles_, spheres_}; }
    // Mesh index and triangle index inside that mesh of a global triangle index (< triangle count).
    [[nodiscard]] std::pair<std::size_t, std::size_t> locate_triangle(std::size_t global_index) const;
    [[nodiscard]] std::size_t triangle_count() const { return triangles_.size(); }
    // Flattens mesh `mesh_index` again after its positions moved; `mesh` has the triangle count it had, and
    // `positions_box` is the box of its positions (which the caller takes while it checks them).
    void refresh_mesh(std::size_t mesh_index, const TriangleMesh& mesh, const Box3f& positions_box);
    // The box of the primitives that can be hit: every triangle, and the spheres of positive radius (what
    // Accel::bounds holds once built on view()).
    [[nodiscard]] Box3f hit_bounds() const;

  private:
    // Writes the triangles of mesh `mesh` from position `first` on, in parallel.
    void write_triangles(std::size_t first, const TriangleMesh& mesh);
    // Writes mesh `mesh_index`'s triangles at their position and takes their box.
    void flatten(std::size_t mesh_index, const TriangleMesh& mesh);

    HugePageVector<Triangle> triangles_;
    std::vector<Sphere> spheres_;
    std::vector<std::size_t> mesh_first_triangle_;  // prefix offsets, one per mesh plus the total
    std::vector<Box3f> mesh_bounds_;                // the box of each mesh's triangles
    std::vector<std::optional<bool>>
        mesh_uses_every_vertex_;  // every vertex is a corner; unknown until asked
};

// The camera of shared/bench/VIEWS.md for a mesh alone: 45 degrees, looking down -z at the box centre from
// 1.05 r / sin(fov / 2), r the half diagonal.
[[nodiscard]] Camera canonical_view(const Box3f& bounds, int width = 1024, int height = 1024);

}  // namespace lancer
