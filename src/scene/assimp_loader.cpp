// The formats lancer does not read by hand (OBJ, STL, glTF, Collada, ...) through assimp. Each mesh that a
// node of the scene graph places becomes one TriangleMesh, in depth-first node order, its vertices moved by
// the node's transform; its faces come out as triangles in face order, and its points and lines are dropped.
// Asked to keep instances (LoadOptions), a mesh placed by several nodes is converted once, in its own frame,
// and each placement becomes a MeshInstance.
//
// assimp runs no post-processing step but the structure check: JoinIdenticalVertices, SortByPType,
// OptimizeMeshes and PreTransformVertices would merge or reorder faces, and triangle numbers must follow
// the file. Polygons are triangulated here by triangulate_polygon rather than by aiProcess_Triangulate,
// which in assimp 5.2 aborts the process (a failed ai_assert) when a damaged file leaves a mesh's
// primitive types inconsistent with its faces.
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <assimp/Importer.hpp>
#include <cmath>
#include <exception>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "accel/instance/affine.hpp"
#include "lancer/load_scene.hpp"
#include "scene/loaders.hpp"
#include "scene/polygon.hpp"
#include "scene/text_reader.hpp"

namespace lancer {

namespace {

Vec3f to_vec3(const aiVector3D& v) {
    return {v.x, v.y, v.z};
}

Material convert_material(const aiMaterial& source) {
    Material material;
    aiColor3D diffuse;
    if (source.Get(AI_MATKEY_COLOR_DIFFUSE, diffuse) == aiReturn_SUCCESS) {
        const Vec3f color{diffuse.r, diffuse.g, diffuse.b};
        if (is_finite(color)) material.color = color;
    }
    return material;
}

// The node transform as an instance's, or none where it is not affine or cannot be inverted (singular, too
// ill-conditioned): InstancedScene's own refusals, checked here so that such a placement is flattened
// instead.
std::optional<Transform> placement(const aiMatrix4x4& m) {
    if (!(m.d1 == 0.0f && m.d2 == 0.0f && m.d3 == 0.0f && m.d4 == 1.0f)) return std::nullopt;
    const Transform transform{{{m.a1, m.a2, m.a3, m.a4}, {m.b1, m.b2, m.b3, m.b4}, {m.c1, m.c2, m.c3, m.c4}}};
    std::string problem;
    (void)invert(transform, problem);
    if (!problem.empty()) return std::nullopt;
    return transform;
}

class AssimpConverter {
  public:
    AssimpConverter(const std::filesystem::path& file, const aiScene& source, bool keep_instances)
        : file_(file), source_(source), keep_instances_(keep_instances) {}

    Scene convert() && {
        for (unsigned i = 0; i < source_.mNumMaterials; ++i)
            scene_.materials.push_back(convert_material(*source_.mMaterials[i]));
        if (source_.mRootNode != nullptr) convert_placements(placements());
        return std::move(scene_);
    }

  private:
    struct Placement {
        unsigned mesh;
        aiMatrix4x4 transform;  // the node's, composed down from the root
    };

    // Every mesh a node places, depth-first, children in order, with an explicit stack: a hostile file can
    // nest nodes deeply.
    [[nodiscard]] std::vector<Placement> placements() const {
        std::vector<Placement> found;
        std::vector<std::pair<const aiNode*, aiMatrix4x4>> stack{
            {source_.mRootNode, source_.mRootNode->mTransformation}};
        while (!stack.empty()) {
            const auto [node, transform] = stack.back();
            stack.pop_back();
            for (unsigned i = 0; i < node->mNumMeshes; ++i) {
                const unsigned mesh = node->mMeshes[i];
                if (mesh >= source_.mNumMeshes)
                    fail("a node refers to mesh " + std::to_string(mesh) + " of " +
                         std::to_string(source_.mNumMeshes));
                found.push_back({mesh, transform});
            }
            for (unsigned i = node->mNumChildren; i-- > 0;) {
                const aiNode* child = node->mChildren[i];
                stack.emplace_back(child, transform * child->mTransformation);
            }
        }
        return found;
    }

    // Each placement a mesh moved by its node, in placement order; with keep_instances, a mesh placed more
    // than once, every placement invertible, is converted once in its own frame and placed by instances.
    void convert_placements(const std::vector<Placement>& placements) {
        std::vector<unsigned> uses(source_.mNumMeshes, 0);
        std::vector<bool> placeable(source_.mNumMeshes, true);
        for (const Placement& p : placements) {
            ++uses[p.mesh];
            placeable[p.mesh] = placeable[p.mesh] && placement(p.transform).has_value();
        }
        // An instanced mesh's index, once converted; a mesh without triangles is placed by no instance.
        constexpr std::uint32_t kNotConverted = std::numeric_limits<std::uint32_t>::max();
        constexpr std::uint32_t kNoTriangles = kNotConverted - 1;
        std::vector<std::uint32_t> instanced(source_.mNumMeshes, kNotConverted);
        for (const Placement& p : placements) {
            if (!(keep_instances_ && uses[p.mesh] > 1 && placeable[p.mesh])) {
                TriangleMesh mesh = convert_mesh(*source_.mMeshes[p.mesh], p.transform);
                if (mesh.triangle_count() > 0) scene_.meshes.push_back(std::move(mesh));
                continue;
            }
            if (instanced[p.mesh] == kNotConverted) {
                TriangleMesh mesh = convert_mesh(*source_.mMeshes[p.mesh], aiMatrix4x4());
                instanced[p.mesh] = mesh.triangle_count() == 0
                                        ? kNoTriangles
                                        : static_cast<std::uint32_t>(scene_.instanced_meshes.size());
                if (mesh.triangle_count() > 0) scene_.instanced_meshes.push_back(std::move(mesh));
            }
            if (instanced[p.mesh] != kNoTriangles)
                scene_.instances.push_back({instanced[p.mesh], *placement(p.transform)});
        }
    }

    // The mesh moved by `transform`, its faces triangles in face order; no triangle where it has only points
    // and lines.
    [[nodiscard]] TriangleMesh convert_mesh(const aiMesh& source, const aiMatrix4x4& transform) {
        TriangleMesh mesh;
        mesh.name = source.mName.length > 0 ? std::string(source.mName.C_Str()) : file_.stem().string();
        if (source.mMaterialIndex >= scene_.materials.size())
            fail("mesh " + mesh.name + " uses a material that does not exist");
        mesh.material = source.mMaterialIndex;

        const bool moved = !transform.IsIdentity();
        mesh.positions.reserve(source.mNumVertices);
        for (unsigned i = 0; i < source.mNumVertices; ++i) {
            const Vec3f position = to_vec3(moved ? transform * source.mVertices[i] : source.mVertices[i]);
            if (!is_finite(position))
                fail("mesh " + mesh.name + ": vertex " + std::to_string(i) + " is not a finite point");
            mesh.positions.push_back(position);
        }
        if (source.HasNormals()) convert_normals(source, transform, mesh);

        mesh.indices.reserve(3 * static_cast<std::size_t>(source.mNumFaces));
        for (unsigned f = 0; f < source.mNumFaces; ++f) {
            const aiFace& face = source.mFaces[f];
            if (face.mNumIndices < 3) continue;  // points and lines
            polygon_.clear();
            for (unsigned k = 0; k < face.mNumIndices; ++k) {
                if (face.mIndices[k] >= source.mNumVertices) {
                    fail("mesh " + mesh.name + ": face " + std::to_string(f) + " index out of range");
                }
                polygon_.push_back(mesh.positions[face.mIndices[k]]);
            }
            corners_.clear();
            if (!triangulate_polygon(polygon_, corners_)) {
                fail("mesh " + mesh.name + ": face " + std::to_string(f) + " is a concave polygon of " +
                     std::to_string(face.mNumIndices) + " vertices, more than the " +
                     std::to_string(kMaxEarClippedVertices) + " ear clipping takes");
            }
            for (const std::uint32_t corner : corners_)
                mesh.indices.push_back(face.mIndices[corner]);
        }
        return mesh;
    }

    // Normals move with the inverse transpose of the node transform. A mesh with one unusable normal (zero or
    // not finite) keeps none: flat shading beats a black or NaN spot.
    static void convert_normals(const aiMesh& source, const aiMatrix4x4& transform, TriangleMesh& mesh) {
        aiMatrix3x3 normal_transform(transform);
        normal_transform.Inverse().Transpose();
        mesh.normals.reserve(source.mNumVertices);
        for (unsigned i = 0; i < source.mNumVertices; ++i) {
            const Vec3f normal = to_vec3(normal_transform * source.mNormals[i]);
            const float norm = length(normal);
            if (!(norm > 0.0f && std::isfinite(norm))) {
                mesh.normals.clear();
                return;
            }
            mesh.normals.push_back(normal / norm);
        }
    }

    [[noreturn]] void fail(const std::string& message) const { throw LoadError(file_, 0, message); }

    const std::filesystem::path& file_;
    const aiScene& source_;
    bool keep_instances_;
    Scene scene_;
    // Scratch space of convert_mesh, kept between faces.
    std::vector<Vec3f> polygon_;
    std::vector<std::uint32_t> corners_;
};

}  // namespace

Scene load_with_assimp(const std::filesystem::path& file, bool keep_instances) {
    // assimp's own message for a missing file is vaguer than ours.
    check_readable(file);
    Assimp::Importer importer;
    const aiScene* source = nullptr;
    try {
        source = importer.ReadFile(file.string(), aiProcess_ValidateDataStructure);
    } catch (const std::exception& error) {
        // assimp catches its own import errors; what escapes (bad_alloc on absurd sizes) is still the file's.
        throw LoadError(file, 0, std::string("assimp: ") + error.what());
    }
    if (source == nullptr) throw LoadError(file, 0, std::string("assimp: ") + importer.GetErrorString());
    if ((source->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0)
        throw LoadError(file, 0, "assimp: the scene is incomplete");
    return AssimpConverter(file, *source, keep_instances).convert();
}

}  // namespace lancer
