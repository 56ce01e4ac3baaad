// The `lancer` Python module (docs/python.md): RaycastingScene with Open3D's signatures and defaults.
#include <pybind11/eval.h>
#include <pybind11/pybind11.h>

#include <limits>

#include "files.hpp"
#include "pinhole_rays.hpp"
#include "raycasting_scene.hpp"

namespace py = pybind11;
using lancer::python::RaycastingScene;

PYBIND11_MODULE(lancer, module) {
    module.doc() = "lancer: exact ray queries over triangle meshes (Open3D's RaycastingScene API)";
    module.attr("__version__") = "0.1.0";
    // Open3D's answers are tensors, and code written for them reads each through numpy(): lancer's are NumPy
    // arrays of this subclass, which adds that method and nothing else.
    py::dict scope;
    scope["numpy"] = py::module_::import("numpy");
    py::exec(R"(
class Array(numpy.ndarray):
    """A NumPy array with Open3D's Tensor.numpy(): the answers of lancer.RaycastingScene."""

    def numpy(self):
        """This array as a plain numpy.ndarray (a view, as Open3D's Tensor.numpy() on the CPU)."""
        return self.view(numpy.ndarray)
)",
             scope);
    scope["Array"].attr("__module__") = "lancer";
    module.attr("Array") = scope["Array"];
    py::class_<RaycastingScene>(module, "RaycastingScene")
        .def(
            py::init<std::string, bool, int>(), py::arg("accel") = std::string(lancer::python::kDefaultAccel),
            py::arg("watertight") = true, py::arg("nthreads") = 0,
            "A scene traced by lancer structure `accel` (lancer.accel_names()), with the watertight triangle "
            "test (Woop et al. 2013) or Moller-Trumbore; nthreads builds the structures (0: all)")
        .def(py::init([](int nthreads) {
                 return std::make_unique<RaycastingScene>(std::string(lancer::python::kDefaultAccel), true,
                                                          nthreads);
             }),
             py::arg("nthreads"),
             "Open3D's constructor: a scene of the default structure, built on nthreads threads (0: all)")
        .def_readonly_static("INVALID_ID", &lancer::python::kInvalidId)
        .def("add_triangles", &RaycastingScene::add_triangles, py::arg("vertex_positions"),
             py::arg("triangle_indices"),
             "Adds a mesh: vertex_positions float32 (N, 3), triangle_indices integer (M, 3). Returns its "
             "geometry id.")
        .def("add_triangles", &RaycastingScene::add_mesh, py::arg("mesh"),
             "Adds an open3d.t.geometry.TriangleMesh. Returns its geometry id.")
        .def("update_vertices", &RaycastingScene::update_vertices, py::arg("geometry_id"),
             py::arg("vertices"),
             "Moves a geometry's vertices, float32 (N, 3) with N its vertex count, its triangles kept;\n"
             "the BVHs refit, the other structures rebuild (deferred before the first query).\n"
             "Returns {method, ms, sah_ratio}.")
        .def("cast_rays", &RaycastingScene::cast_rays, py::arg("rays"), py::arg("nthreads") = 0,
             "Closest hits of rays float32 (..., 6): t_hit, geometry_ids, primitive_ids, primitive_uvs, "
             "primitive_normals")
        .def("test_occlusions", &RaycastingScene::test_occlusions, py::arg("rays"), py::arg("tnear") = 0.0f,
             py::arg("tfar") = std::numeric_limits<float>::infinity(), py::arg("nthreads") = 0,
             "Whether each ray hits anything within [tnear, tfar]")
        .def("count_intersections", &RaycastingScene::count_intersections, py::arg("rays"),
             py::arg("nthreads") = 0, "The number of hits along each ray")
        .def("list_intersections", &RaycastingScene::list_intersections, py::arg("rays"),
             py::arg("nthreads") = 0,
             "Every hit along each ray, by increasing t: ray_splits, ray_ids, geometry_ids, primitive_ids, "
             "primitive_uvs, t_hit")
        .def("compute_closest_points", &RaycastingScene::compute_closest_points, py::arg("query_points"),
             py::arg("nthreads") = 0,
             "The nearest surface point of each query point (..., 3): points, geometry_ids, primitive_ids, "
             "primitive_uvs, primitive_normals")
        .def("compute_distance", &RaycastingScene::compute_distance, py::arg("query_points"),
             py::arg("nthreads") = 0, "The distance from each query point to the surface")
        .def("compute_occupancy", &RaycastingScene::compute_occupancy, py::arg("query_points"),
             py::arg("nthreads") = 0, py::arg("nsamples") = 1,
             "1 inside the closed meshes, 0 outside: the parity of ray crossings, by majority of nsamples "
             "rays")
        .def("compute_signed_distance", &RaycastingScene::compute_signed_distance, py::arg("query_points"),
             py::arg("nthreads") = 0, py::arg("nsamples") = 1,
             "The distance to the surface, negative inside the closed meshes (compute_occupancy's rule)")
        .def_static(
            "create_rays_pinhole",
            py::overload_cast<double, const py::object&, const py::object&, const py::object&, int, int>(
                &lancer::python::create_rays_pinhole),
            py::arg("fov_deg"), py::arg("center"), py::arg("eye"), py::arg("up"), py::arg("width_px"),
            py::arg("height_px"),
            "Rays (height_px, width_px, 6) of a pinhole camera at `eye` looking at `center`")
        .def_static("create_rays_pinhole",
                    py::overload_cast<const py::object&, const py::object&, int, int>(
                        &lancer::python::create_rays_pinhole),
                    py::arg("intrinsic_matrix"), py::arg("extrinsic_matrix"), py::arg("width_px"),
                    py::arg("height_px"),
                    "Rays (height_px, width_px, 6) of a pinhole camera: intrinsic_matrix K (3, 3), "
                    "extrinsic_matrix the world-to-camera transform (4, 4)")
        .def("save_structure", &RaycastingScene::save_structure, py::arg("path"),
             "lancer's own: writes the `plucker` structure and its triangles as a .plo file")
        .def_static(
            "load_structure", &RaycastingScene::load_structure, py::arg("path"),
            py::arg("watertight") = py::none(),
            "lancer's own: a `plucker` scene read from a .plo file (lancer convert's), its triangles one "
            "geometry; watertight None keeps the file's triangle test")
        .def_property_readonly("accel", &RaycastingScene::accel)
        .def("stats", &RaycastingScene::stats, "The structure's build statistics");
    module.def(
        "accel_names",
        [] {
            py::list names;
            for (const std::string_view name : lancer::accel_names())
                names.append(std::string(name));
            return names;
        },
        "The structures RaycastingScene(accel=...) takes");
    module.def("load_mesh", &lancer::python::load_mesh, py::arg("path"),
               "(vertices float32 (N, 3), triangles uint32 (M, 3)) of a mesh file (OFF, PLY, OBJ, NFF, ...)");
    module.def("save_png", &lancer::python::save_png, py::arg("path"), py::arg("image"),
               "Writes linear values in [0, 1], (H, W) or (H, W, 3), as an 8-bit sRGB PNG");
}
