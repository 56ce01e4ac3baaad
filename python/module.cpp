// The `lancer` Python module (docs/python.md): RaycastingScene with Open3D's signatures and defaults.
#include <pybind11/eval.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <limits>
#include <optional>
#include <type_traits>

#include "array_arguments.hpp"
#include "files.hpp"
#include "instanced_scene.hpp"
#include "named_types.hpp"
#include "pinhole_rays.hpp"
#include "raycasting_scene.hpp"

namespace py = pybind11;
using lancer::python::ArrayLike;
using lancer::python::InstancedScene;
using lancer::python::Named;
using lancer::python::RaycastingScene;

namespace {

// A query as Python sees it: its first argument (rays or points) named as an array in the signature, and its
// answers Open3D tensors when that argument is one (tensors_like), lancer.Array otherwise.
template <class Scene, class Answer, class... Rest>
auto query(Answer (Scene::*method)(const py::object&, Rest...)) {
    using Answers =
        std::conditional_t<std::is_same_v<Answer, py::dict>, Named<lancer::python::AnswerDictName>,
                           Named<lancer::python::AnswerArrayName>>;
    return [method](Scene& scene, const ArrayLike& first, Rest... rest) {
        return Answers{lancer::python::tensors_like(first.object, (scene.*method)(first.object, rest...))};
    };
}

// The two add_triangles of a scene: arrays (documented by `arrays_doc`), or Open3D's mesh.
template <class Scene>
void add_triangles_methods(py::class_<Scene>& scene_class, const char* arrays_doc) {
    scene_class
        .def(
            "add_triangles",
            [](Scene& scene, const ArrayLike& vertex_positions, const ArrayLike& triangle_indices) {
                return scene.add_triangles(vertex_positions.object, triangle_indices.object);
            },
            py::arg("vertex_positions"), py::arg("triangle_indices"), arrays_doc)
        .def(
            "add_triangles",
            [](Scene& scene, const Named<lancer::python::TriangleMeshName>& mesh) {
                return scene.add_mesh(mesh.object);
            },
            py::arg("mesh"),
            "Adds an open3d.t.geometry.TriangleMesh (its vertex['positions'] and triangle['indices']) and\n"
            "returns its geometry id.");
}

// What every query's docstring says of its rays or points and of Open3D's tensors.
#define LANCER_RAYS_DOC                                                                                     \
    "rays: (..., 6) origins and directions (the direction need not be a unit vector; t is in its units),\n" \
    "  float32 read in place; float64, integer arrays and lists are converted to float32 once.\n"
#define LANCER_POINTS_DOC                                                                                 \
    "query_points: (..., 3), float32 read in place; float64, integer arrays and lists are converted to\n" \
    "  float32 once.\n"
#define LANCER_COMMON_DOC                                                                                 \
    "nthreads: the threads that trace (0: all; more than the machine has count as all).\n"                \
    "Answers keep the leading shape (...) as lancer.Array (NumPy arrays with Open3D's Tensor.numpy());\n" \
    "given an open3d.core.Tensor, answers are open3d.core.Tensor. Queries from several threads run at "   \
    "once.\n"

}  // namespace

PYBIND11_MODULE(lancer, module) {
    module.doc() = "lancer: exact ray queries over triangle meshes (Open3D's RaycastingScene API)";
    module.attr("__version__") = "0.1.0";
    // Open3D's answers are tensors, and code written for them reads each through numpy() (and, in Open3D's
    // tutorial, isfinite()): lancer's are NumPy arrays of this subclass, which adds those, and whose
    // arithmetic gives plain arrays.
    py::dict scope;
    scope["numpy"] = py::module_::import("numpy");
    py::exec(R"(
class Array(numpy.ndarray):
    """A NumPy array with Open3D's Tensor.numpy() and Tensor.isfinite(): the answers of lancer.RaycastingScene."""

    def numpy(self):
        """This array as a plain numpy.ndarray (a view, as Open3D's Tensor.numpy() on the CPU)."""
        return self.view(numpy.ndarray)

    def isfinite(self):
        """Whether each value is finite, a bool array of the same shape (Open3D's Tensor.isfinite())."""
        return numpy.isfinite(self)

    def __array_wrap__(self, array, context=None, return_scalar=False):
        # What arithmetic makes of answers is a plain array (a scalar for no axes), which Open3D takes:
        # o3d.t.geometry.PointCloud(points) refuses subclasses, as the tutorial's last cell would meet.
        return array.view(numpy.ndarray) if array.ndim else array[()]
)",
             scope);
    scope["Array"].attr("__module__") = "lancer";
    module.attr("Array") = scope["Array"];
    py::class_<RaycastingScene> raycasting_scene(
        module, "RaycastingScene",
        "Exact ray and point queries over triangle meshes, with the API of Open3D's\n"
        "open3d.t.geometry.RaycastingScene (0.16, and 0.17's list_intersections): switch by changing the "
        "import.\n"
        "\n"
        "Add meshes (add_triangles), then query: cast_rays, test_occlusions, count_intersections,\n"
        "list_intersections, compute_closest_points, compute_distance, compute_occupancy,\n"
        "compute_signed_distance. The structure (`accel`, one of lancer.accel_names()) is built by the "
        "first\n"
        "query after a change. Arrays are NumPy's, anything NumPy converts (float64 and lists are converted "
        "to\n"
        "float32 once), or Open3D tensors, which give tensors back. Queries release the GIL and run at once\n"
        "from several threads; a scene pickles (its meshes; the structure is rebuilt). docs/python.md has "
        "the\n"
        "details.");
    add_triangles_methods(
        raycasting_scene,
        "Adds a mesh and returns its geometry id (0, 1, ...).\n"
        "vertex_positions: (N, 3) float32 (float64 and lists are converted); triangle_indices: "
        "(M, 3)\n"
        "integers (uint32 as Open3D's; any integer dtype or lists), each in [0, N).");
    raycasting_scene
        .def(py::init<std::string, bool, int>(),
             py::arg("accel") = std::string(lancer::python::kDefaultAccel), py::arg("watertight") = true,
             py::arg("nthreads") = 0,
             "A scene traced by lancer structure `accel` (lancer.accel_names()), with the watertight "
             "triangle\n"
             "test (Woop et al. 2013) or Moller-Trumbore; nthreads: the threads that build the structures "
             "(0:\n"
             "all).")
        .def(py::init([](int nthreads) {
                 return std::make_unique<RaycastingScene>(std::string(lancer::python::kDefaultAccel), true,
                                                          nthreads);
             }),
             py::arg("nthreads"),
             "Open3D's constructor: a scene of the default structure (bvh8_packet), built on nthreads "
             "threads (0: all).")
        .def_readonly_static("INVALID_ID", &lancer::python::kInvalidId)
        .def(
            "update_vertices",
            [](RaycastingScene& scene, const Named<lancer::python::IndexName>& geometry_id,
               const ArrayLike& vertices) {
                return scene.update_vertices(geometry_id.object, vertices.object);
            },
            py::arg("geometry_id"), py::arg("vertices"),
            "lancer's own: moves a geometry's vertices, its triangles kept.\n"
            "geometry_id: an id add_triangles returned (any integer type); vertices: (N, 3) float32 "
            "(float64\n"
            "and lists are converted), N the geometry's vertex count. The BVHs refit, the other structures\n"
            "rebuild (deferred before the first query). Returns {method, ms, sah_ratio}.")
        .def(
            "cast_rays", query(&RaycastingScene::cast_rays), py::arg("rays"), py::arg("nthreads") = 0,
            "The closest hit of each ray.\n" LANCER_RAYS_DOC LANCER_COMMON_DOC
            "Returns a dict: t_hit float32 (...) (inf: a miss), geometry_ids uint32 (...) (INVALID_ID: a "
            "miss),\n"
            "primitive_ids uint32 (...), primitive_uvs float32 (..., 2), primitive_normals float32 (..., 3)\n"
            "(the unit geometric normal; zeros for a miss).")
        .def("test_occlusions", query(&RaycastingScene::test_occlusions), py::arg("rays"),
             py::arg("tnear") = 0.0f, py::arg("tfar") = std::numeric_limits<float>::infinity(),
             py::arg("nthreads") = 0,
             "Whether each ray hits anything with t in [tnear, tfar].\n" LANCER_RAYS_DOC LANCER_COMMON_DOC
             "Returns bool (...).")
        .def("count_intersections", query(&RaycastingScene::count_intersections), py::arg("rays"),
             py::arg("nthreads") = 0,
             "The number of hits along each ray.\n" LANCER_RAYS_DOC LANCER_COMMON_DOC "Returns int32 (...).")
        .def("list_intersections", query(&RaycastingScene::list_intersections), py::arg("rays"),
             py::arg("nthreads") = 0,
             "Every hit along each ray, by increasing t.\n" LANCER_RAYS_DOC LANCER_COMMON_DOC
             "Returns a dict of flat arrays: ray_splits uint32 (rays + 1) (ray i's hits are\n"
             "[ray_splits[i], ray_splits[i + 1])), ray_ids, geometry_ids, primitive_ids uint32 (hits),\n"
             "primitive_uvs float32 (hits, 2), t_hit float32 (hits).")
        .def("compute_closest_points", query(&RaycastingScene::compute_closest_points),
             py::arg("query_points"), py::arg("nthreads") = 0,
             "The nearest surface point of each query point.\n" LANCER_POINTS_DOC LANCER_COMMON_DOC
             "Returns a dict: points float32 (..., 3), geometry_ids uint32 (...), primitive_ids uint32 "
             "(...),\n"
             "primitive_uvs float32 (..., 2), primitive_normals float32 (..., 3).")
        .def("compute_distance", query(&RaycastingScene::compute_distance), py::arg("query_points"),
             py::arg("nthreads") = 0,
             "The distance from each query point to the surface.\n" LANCER_POINTS_DOC LANCER_COMMON_DOC
             "Returns float32 (...).")
        .def("compute_occupancy", query(&RaycastingScene::compute_occupancy), py::arg("query_points"),
             py::arg("nthreads") = 0, py::arg("nsamples") = 1,
             "1 inside the closed meshes, 0 outside: the parity of ray crossings, by majority of nsamples\n"
             "rays (1 to 1024).\n" LANCER_POINTS_DOC LANCER_COMMON_DOC "Returns float32 (...).")
        .def("compute_signed_distance", query(&RaycastingScene::compute_signed_distance),
             py::arg("query_points"), py::arg("nthreads") = 0, py::arg("nsamples") = 1,
             "The distance to the surface, negative inside the closed meshes (compute_occupancy's "
             "rule).\n" LANCER_POINTS_DOC LANCER_COMMON_DOC "Returns float32 (...).")
        .def_static(
            "create_rays_pinhole",
            [](double fov_deg, const ArrayLike& center, const ArrayLike& eye, const ArrayLike& up,
               int width_px, int height_px) {
                return Named<lancer::python::AnswerArrayName>{lancer::python::create_rays_pinhole(
                    fov_deg, center.object, eye.object, up.object, width_px, height_px)};
            },
            py::arg("fov_deg"), py::arg("center"), py::arg("eye"), py::arg("up"), py::arg("width_px"),
            py::arg("height_px"),
            "Rays float32 (height_px, width_px, 6) of a pinhole camera at `eye` looking at `center`, `up`\n"
            "(3 numbers each) fixing its roll, with a horizontal field of view of fov_deg degrees.")
        .def_static(
            "create_rays_pinhole",
            [](const ArrayLike& intrinsic_matrix, const ArrayLike& extrinsic_matrix, int width_px,
               int height_px) {
                return Named<lancer::python::AnswerArrayName>{lancer::python::create_rays_pinhole(
                    intrinsic_matrix.object, extrinsic_matrix.object, width_px, height_px)};
            },
            py::arg("intrinsic_matrix"), py::arg("extrinsic_matrix"), py::arg("width_px"),
            py::arg("height_px"),
            "Rays float32 (height_px, width_px, 6) of a pinhole camera: intrinsic_matrix K (3, 3),\n"
            "extrinsic_matrix the world-to-camera transform (4, 4), any dtype NumPy converts.")
        .def("save_structure", &RaycastingScene::save_structure, py::arg("path"),
             "lancer's own: writes the `plucker` structure and its triangles as a .plo file (path: str or\n"
             "os.PathLike).")
        .def_static(
            "load_structure", &RaycastingScene::load_structure, py::arg("path"),
            py::arg("watertight") = py::none(),
            "lancer's own: a `plucker` scene read from a .plo file (lancer convert's), its triangles one\n"
            "geometry; watertight None keeps the file's triangle test.")
        .def(py::pickle(
            [](RaycastingScene& scene) { return Named<lancer::python::StateName>{scene.pickled()}; },
            [](const Named<lancer::python::StateName>& state) {
                return RaycastingScene::unpickled(state.object);
            }))
        .def_property_readonly("accel", &RaycastingScene::accel,
                               "The structure's name (lancer.accel_names()).")
        .def("stats", &RaycastingScene::stats,
             "The structure's build statistics: accel, primitives, build_ms, the structure's own figures,\n"
             "memory_bytes.");
    py::class_<InstancedScene> instanced_scene(
        module, "InstancedScene",
        "Geometries built once and placed any number of times by instances, each an affine transform: a\n"
        "forest of a few trees, a city of a few buildings. lancer's two-level scene (Embree's instances,\n"
        "OptiX's instance acceleration structures) with RaycastingScene's conventions.\n"
        "\n"
        "add_triangles gives a geometry id (the geometry is built then, and placed by no instance yet);\n"
        "add_instance(geometry_id, transform) an instance id; set_transform and remove_instance move and\n"
        "remove instances, which updates the top level only. cast_rays answers as RaycastingScene's, the\n"
        "geometry and primitive those of the instanced geometry, with instance_ids besides. A scene pickles\n"
        "(its geometries and instances; the structures are rebuilt). docs/python.md, \"Instances\", has the\n"
        "details.");
    add_triangles_methods(
        instanced_scene,
        "Adds a geometry, builds its structure, and returns its geometry id (0, 1, ...); no "
        "instance\n"
        "places it yet. vertex_positions: (N, 3) float32 (float64 and lists are converted);\n"
        "triangle_indices: (M, 3) integers, each in [0, N), M at least 1.");
    instanced_scene
        .def(py::init<std::string, bool, int>(),
             py::arg("accel") = std::string(lancer::python::kDefaultInstancedAccel),
             py::arg("watertight") = true, py::arg("nthreads") = 0,
             "A scene whose geometries are built as lancer structure `accel` (lancer.accel_names()), with "
             "the\n"
             "watertight triangle test (Woop et al. 2013) or Moller-Trumbore; nthreads: the threads that "
             "build\n"
             "the geometries and the top level (0: all).")
        .def(
            "add_instance",
            [](InstancedScene& scene, const Named<lancer::python::IndexName>& geometry_id,
               const ArrayLike& transform) {
                return scene.add_instance(geometry_id.object, transform.object);
            },
            py::arg("geometry_id"), py::arg("transform"),
            "Places geometry geometry_id by transform, object to world: a (3, 4) matrix [A | b] (a point p\n"
            "goes to A p + b), or (4, 4) with the last row (0, 0, 0, 1); any real dtype, rounded to float32\n"
            "once. Returns the instance id: 0, 1, ... in order of addition, never given again after\n"
            "remove_instance. A transform with a NaN or infinite entry, a singular or too ill-conditioned\n"
            "one (condition number above 2^29), or one that takes the geometry outside the coordinate "
            "domain\n"
            "raises ValueError, the scene unchanged.")
        .def(
            "set_transform",
            [](InstancedScene& scene, const Named<lancer::python::IndexName>& instance_id,
               const ArrayLike& transform) { scene.set_transform(instance_id.object, transform.object); },
            py::arg("instance_id"), py::arg("transform"),
            "Moves an instance: transform as add_instance's. The top level is refitted (or rebuilt once\n"
            "its cost degrades) by the next query; the geometries are not touched.")
        .def(
            "remove_instance",
            [](InstancedScene& scene, const Named<lancer::python::IndexName>& instance_id) {
                scene.remove_instance(instance_id.object);
            },
            py::arg("instance_id"), "Removes an instance; its id is never given again.")
        .def(py::pickle(
            [](InstancedScene& scene) { return Named<lancer::python::StateName>{scene.pickled()}; },
            [](const Named<lancer::python::StateName>& state) {
                return InstancedScene::unpickled(state.object);
            }))
        .def("cast_rays", query(&InstancedScene::cast_rays), py::arg("rays"), py::arg("nthreads") = 0,
             "The closest hit of each ray over every instance.\n" LANCER_RAYS_DOC LANCER_COMMON_DOC
             "Returns a dict: t_hit float32 (...) (inf: a miss; in the world ray's units), geometry_ids,\n"
             "primitive_ids and instance_ids uint32 (...) (INVALID_ID: a miss), primitive_uvs float32\n"
             "(..., 2) in the geometry's vertex order, primitive_normals float32 (..., 3) (the world's unit\n"
             "geometric normal: the transformed triangle's (v1 - v0) x (v2 - v0); zeros for a miss).")
        .def("test_occlusions", query(&InstancedScene::test_occlusions), py::arg("rays"),
             py::arg("tnear") = 0.0f, py::arg("tfar") = std::numeric_limits<float>::infinity(),
             py::arg("nthreads") = 0,
             "Whether each ray hits any instance with t in [tnear, tfar].\n" LANCER_RAYS_DOC LANCER_COMMON_DOC
             "Returns bool (...).")
        .def_property_readonly("accel", &InstancedScene::accel,
                               "The geometries' structure (lancer.accel_names()).")
        .def("stats", &InstancedScene::stats,
             "accel, geometries, instances, triangles (the geometries' own), instanced_triangles (over the\n"
             "instances: what the scene flattened would hold), the top level's build ms and figures, and\n"
             "memory_bytes (the top level, the instances' records and the geometries' structures).");
    module.def(
        "accel_names",
        [] {
            py::list names;
            for (const std::string_view name : lancer::accel_names())
                names.append(std::string(name));
            return names;
        },
        "The structures RaycastingScene(accel=...) takes.");
    module.def(
        "load_mesh", &lancer::python::load_mesh, py::arg("path"),
        "(vertices float32 (N, 3), triangles uint32 (M, 3)) of every mesh of a file (OFF, PLY, OBJ, NFF,\n"
        "assimp's formats); path: str or os.PathLike.");
    module.def(
        "save_png",
        [](const std::filesystem::path& path, const ArrayLike& image) {
            lancer::python::save_png(path, image.object);
        },
        py::arg("path"), py::arg("image"),
        "Writes an image of linear values in [0, 1], float (H, W) or (H, W, 3), as an 8-bit sRGB PNG.");
}
