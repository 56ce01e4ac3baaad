#include "raycasting_scene.hpp"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <stdexcept>

#include "array_arguments.hpp"
#include "lancer/parallel.hpp"

namespace lancer::python {

using namespace pybind11::literals;

namespace {

// Rays first to last of the (..., 6) rows, with the interval [tnear, tfar]. Throws std::invalid_argument
// (ValueError) for a row with a NaN or infinite value, as float_rows does.
void rays_of(const py::array_t<float, py::array::c_style>& rows, std::size_t first, std::size_t last,
             float tnear, float tfar, std::vector<Ray>& rays) {
    rays.clear();
    for (std::size_t i = first; i < last; ++i) {
        const float* r = rows.data() + 6 * i;
        if (!(std::isfinite(r[0]) && std::isfinite(r[1]) && std::isfinite(r[2]) && std::isfinite(r[3]) &&
              std::isfinite(r[4]) && std::isfinite(r[5])))
            throw std::invalid_argument("rays: " + row_name(rows, i) + " holds a NaN or infinite value");
        rays.push_back({{r[0], r[1], r[2]}, {r[3], r[4], r[5]}, tnear, tfar});
    }
}

// Items per task of the queries: a chunk of rays is one batch call, as intersect_parallel makes them, and as
// the chunks start at multiples of kChunk, its packets of 64 start at multiples of 64.
constexpr std::size_t kChunk = 4096;

// body(first, rays) for each chunk of the (..., 6) rows, on `threads` threads (0: all): the rays first to
// first + rays.size(), made by the task that traces them (rays_of).
template <class Body>
void for_each_ray_chunk(const py::array_t<float, py::array::c_style>& rows, int threads, float tnear,
                        float tfar, Body&& body) {
    parallel_for(static_cast<std::size_t>(rows.size() / 6), kChunk, threads,
                 [&](std::size_t first, std::size_t last) {
                     std::vector<Ray> rays;
                     rays_of(rows, first, last, tnear, tfar, rays);
                     body(first, rays);
                 });
}

// `samples` fixed directions in no plane of the axes, so that axis-aligned meshes do not put their edges on
// the occupancy rays: the fractional parts of multiples of three irrationals, centred.
std::vector<Vec3f> sample_directions(int samples) {
    std::vector<Vec3f> directions;
    for (int k = 0; k < samples; ++k) {
        const auto component = [&](double irrational, double offset) {
            const double x = (k + 1) * irrational + offset;
            return static_cast<float>(x - std::floor(x) - 0.5);
        };
        directions.push_back(normalize(
            Vec3f(component(0.6180339887, 0.1), component(0.4142135623, 0.3), component(0.7320508075, 0.7))));
    }
    return directions;
}

// The indices of an (M, 3) integer array, checked against the vertex count, read as Index: int64, or uint64
// for unsigned dtypes, so that an index is reported as given (2**63 + 1, not wrapped to a negative).
template <class Index>
void read_indices(const py::array& array, std::size_t vertex_count, const std::string& name,
                  std::vector<std::uint32_t>& indices) {
    const auto rows = py::array_t<Index, py::array::c_style | py::array::forcecast>::ensure(array);
    const Index* index = rows.data();
    indices.reserve(static_cast<std::size_t>(rows.size()));
    for (py::ssize_t k = 0; k < rows.size(); ++k) {
        if (std::cmp_less(index[k], 0) || std::cmp_greater_equal(index[k], vertex_count))
            throw py::value_error(name + ": row " + std::to_string(k / 3) + " names vertex " +
                                  std::to_string(index[k]) + ", outside [0, " + std::to_string(vertex_count) +
                                  ")");
        indices.push_back(static_cast<std::uint32_t>(index[k]));
    }
}

void check_samples(int nsamples) {
    if (nsamples < 1 || nsamples > 1024)
        throw py::value_error("nsamples: expected a count in [1, 1024], got " + std::to_string(nsamples));
}

}  // namespace

RaycastingScene::RaycastingScene(std::string accel, bool watertight, int nthreads)
    : accel_name_(std::move(accel)),
      test_(watertight ? TriangleTest::Watertight : TriangleTest::MollerTrumbore),
      build_threads_(nthreads),
      first_triangle_{0} {
    check_threads(nthreads);
    scene_.materials.emplace_back();  // the meshes' material 0: a World renders what it holds
    const std::vector<std::string_view> names = accel_names();
    if (std::find(names.begin(), names.end(), accel_name_) == names.end()) {
        std::string known;
        for (const std::string_view name : names)
            known.append(known.empty() ? "" : ", ").append(name);
        throw py::value_error("accel: unknown structure '" + accel_name_ + "' (known: " + known + ")");
    }
}

std::uint32_t RaycastingScene::add_triangles(const py::object& vertex_positions,
                                             const py::object& triangle_indices) {
    return add_geometry(vertex_positions, triangle_indices, "vertex_positions", "triangle_indices");
}

std::uint32_t RaycastingScene::add_mesh(const py::object& mesh) {
    const py::handle type = py::type::of(mesh);
    const std::string type_name =
        std::string(py::str(type.attr("__module__"))) + "." + std::string(py::str(type.attr("__qualname__")));
    if (!py::hasattr(mesh, "vertex") || !py::hasattr(mesh, "triangle")) {
        throw py::type_error(
            "mesh: expected an open3d.t.geometry.TriangleMesh (from_legacy() converts a legacy "
            "open3d.geometry.TriangleMesh), got " +
            type_name);
    }
    py::object positions, indices;
    try {
        positions = mesh.attr("vertex")["positions"];
        indices = mesh.attr("triangle")["indices"];
    } catch (const py::error_already_set&) {
        throw py::value_error("mesh: expected vertex['positions'] and triangle['indices'], a " + type_name +
                              " without them");
    }
    return add_geometry(positions, indices, "mesh.vertex['positions']", "mesh.triangle['indices']");
}

std::uint32_t RaycastingScene::add_geometry(const py::object& vertices, const py::object& triangles,
                                            const std::string& vertices_name,
                                            const std::string& triangles_name) {
    const auto points = float_rows(vertices, vertices_name, 3);
    py::object indices_object = numpy_of(triangles);
    try {
        indices_object = py::module_::import("numpy").attr("asarray")(indices_object);  // lists too
    } catch (const py::error_already_set&) {
        throw py::type_error(triangles_name + ": expected an array of integers");
    }
    const auto indices_array = py::reinterpret_borrow<py::array>(indices_object);
    const char kind = indices_array.dtype().kind();
    if (kind != 'i' && kind != 'u')
        throw py::type_error(triangles_name + ": expected an integer dtype (uint32 as Open3D), got " +
                             std::string(py::str(indices_array.dtype())));
    if (indices_array.ndim() != 2 || indices_array.shape(1) != 3)
        throw py::value_error(triangles_name + ": expected shape (M, 3), got " + shape_text(indices_array));
    if (points.ndim() != 2)
        throw py::value_error(vertices_name + ": expected shape (N, 3), got " + shape_text(points));
    const auto vertex_count = static_cast<std::size_t>(points.shape(0));
    const float* p = points.data();
    for (py::ssize_t i = 0; i < points.shape(0); ++i) {
        if (!in_coordinate_domain({p[3 * i], p[3 * i + 1], p[3 * i + 2]}))
            throw py::value_error(vertices_name + ": row " + std::to_string(i) +
                                  " lies outside the coordinate domain [-2^60, 2^60]");
    }
    TriangleMesh mesh;
    mesh.name = "geometry " + std::to_string(first_triangle_.size() - 1);
    mesh.positions.reserve(static_cast<std::size_t>(points.shape(0)));
    for (py::ssize_t i = 0; i < points.shape(0); ++i)
        mesh.positions.emplace_back(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    if (kind == 'u')
        read_indices<std::uint64_t>(indices_array, vertex_count, triangles_name, mesh.indices);
    else
        read_indices<std::int64_t>(indices_array, vertex_count, triangles_name, mesh.indices);
    py::gil_scoped_release released;
    const std::unique_lock lock = writing();
    const std::size_t total = first_triangle_.back() + mesh.triangle_count();
    if (total > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        throw std::invalid_argument(triangles_name + ": more triangles than a hit's 32-bit id can number");
    first_triangle_.push_back(static_cast<std::uint32_t>(total));
    scene_.meshes.push_back(std::move(mesh));
    queries_.reset();  // first: it reads the World's triangles
    unit_normals_.clear();
    world_.reset();
    return static_cast<std::uint32_t>(first_triangle_.size() - 2);
}

py::dict RaycastingScene::update_vertices(const py::object& geometry_id, const py::object& vertices) {
    const IndexArgument id = index_argument(geometry_id, "geometry_id");
    const auto points = float_rows(vertices, "vertices", 3);
    if (points.ndim() != 2)
        throw py::value_error("vertices: expected shape (N, 3), got " + shape_text(points));
    std::optional<UpdateReport> report;  // none while the structure is not built yet
    {
        py::gil_scoped_release released;
        const std::unique_lock lock = writing();
        if (!id.value || *id.value >= scene_.meshes.size()) {
            throw py::value_error("geometry_id: " + id.text + ", the scene has " +
                                  std::to_string(scene_.meshes.size()) + " geometries");
        }
        const auto geometry = static_cast<std::size_t>(*id.value);
        TriangleMesh& mesh = scene_.meshes[geometry];
        const auto count = static_cast<std::size_t>(points.shape(0));
        if (count != mesh.positions.size()) {
            throw py::value_error("vertices: " + std::to_string(count) + " rows for geometry " +
                                  std::to_string(geometry) + ", which has " +
                                  std::to_string(mesh.positions.size()) + " vertices");
        }
        const float* p = points.data();
        std::vector<Vec3f> positions(count);
        for (std::size_t i = 0; i < count; ++i) {
            positions[i] = {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
            if (!in_coordinate_domain(positions[i]))
                throw py::value_error("vertices: row " + std::to_string(i) +
                                      " lies outside the coordinate domain [-2^60, 2^60]");
        }
        // The structure follows (a refit for the BVHs) once built; before, the next query builds it.
        if (world_) {
            queries_.reset();  // its own tree is over the triangles about to move
            unit_normals_.clear();
            building([&] { report = world_->update_vertices(geometry, positions); });
        }
        mesh.positions = std::move(positions);
    }
    if (!report) return py::dict("method"_a = "deferred", "ms"_a = 0.0, "sah_ratio"_a = 1.0);
    return py::dict("method"_a = report->method == UpdateMethod::Refit ? "refit" : "rebuild",
                    "ms"_a = report->ms, "sah_ratio"_a = report->sah_ratio);
}

std::shared_lock<std::shared_mutex> RaycastingScene::reading() {
    const std::lock_guard turn(turnstile_);
    return std::shared_lock(mutex_);
}

std::unique_lock<std::shared_mutex> RaycastingScene::writing() {
    const std::lock_guard turn(turnstile_);
    return std::unique_lock(mutex_);
}

bool RaycastingScene::ready(unsigned needs) const {
    return world_ && (!(needs & kQueries) || queries_) && (!(needs & kNormals) || !unit_normals_.empty());
}

std::shared_lock<std::shared_mutex> RaycastingScene::prepared(unsigned needs) {
    // Readers cannot turn their lock into a writer's, so a query that finds something missing lets go and
    // builds it under the exclusive lock; a change of the triangles may come in between, hence the loop.
    for (;;) {
        std::shared_lock lock = reading();
        if (ready(needs)) return lock;
        lock.unlock();
        const std::unique_lock exclusive = writing();
        prepare(needs);
    }
}

void RaycastingScene::prepare(unsigned needs) {
    if (first_triangle_.back() == 0) throw std::invalid_argument("the scene is empty: add_triangles first");
    if (!world_)
        building([&] { world_ = std::make_unique<World>(scene_, accel_name_, build_options(test_)); });
    if ((needs & kQueries) && !queries_)
        building([&] {
            queries_ = std::make_unique<GeometryQueries>(world_->accel(), world_->geometry().view(), test_);
        });
    if ((needs & kNormals) && unit_normals_.empty()) {
        const std::span<const Triangle> triangles = world_->geometry().view().triangles;
        // NormalTable's layout: a miss's zero normal, the triangles', one float for the last 4-float load.
        unit_normals_.reserve(3 * triangles.size() + 4);
        unit_normals_.assign(3, 0.0f);
        for (const Triangle& tri : triangles) {
            // A triangle of zero area has no direction to normalise (0 / 0): its normal is the zero vector,
            // as a miss's, rather than NaN (docs/python.md).
            const Vec3f normal = tri.geometric_normal();
            const float norm = length(normal);
            const Vec3f unit = norm > 0.0f ? normal / norm : Vec3f(0.0f);
            unit_normals_.insert(unit_normals_.end(), {unit.x, unit.y, unit.z});
        }
        unit_normals_.push_back(0.0f);
    }
}

std::pair<std::uint32_t, std::uint32_t> RaycastingScene::locate(std::int32_t prim) const {
    return GeometryStarts{first_triangle_}.locate(prim);
}

py::dict RaycastingScene::cast_rays(const py::object& rays, int nthreads) {
    const auto rows = float_rows(rays, "rays", 6, false);
    check_threads(nthreads);
    py::array_t<float> t_hit = line_aligned_array<float>(answer_shape(rows));
    py::array_t<std::uint32_t> geometry_ids = line_aligned_array<std::uint32_t>(answer_shape(rows));
    py::array_t<std::uint32_t> primitive_ids = line_aligned_array<std::uint32_t>(answer_shape(rows));
    py::array_t<float> uvs = line_aligned_array<float>(answer_shape(rows, {2}));
    py::array_t<float> normals = line_aligned_array<float>(answer_shape(rows, {3}));
    const CastAnswers answers{t_hit.mutable_data(), geometry_ids.mutable_data(), primitive_ids.mutable_data(),
                              uvs.mutable_data(), normals.mutable_data()};
    const std::vector<py::ssize_t> leading = answer_shape(rows);
    const RayChunks chunks(std::vector<std::size_t>(leading.begin(), leading.end()));
    {
        // The buffers are filled without the GIL; the lock keeps another thread's add_triangles out. Each
        // chunk of rays is loaded, traced and answered by one task, so that the conversions run in parallel
        // too.
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kNormals);
        const Accel& accel = committed();
        const HitTables tables{unit_normals(), GeometryStarts{first_triangle_}};
        // A chunk's rays are one Accel::intersect batch call, where a structure regroups the rays its
        // packets cannot trace together (docs/python.md, "Speed"); its answers then go packet by packet.
        parallel_for(chunks.size(), 1, nthreads, [&](std::size_t index, std::size_t) {
            thread_local std::vector<PacketRows> packets;
            thread_local std::vector<Ray> batch;
            thread_local std::vector<Hit> batch_hits;
            chunks.chunk(index, packets);
            const std::size_t bad = load_ray_records(rows.data(), packets, batch);
            if (bad < packets.size()) {
                throw std::invalid_argument(
                    "rays: " + row_name(rows, first_bad_row(rows.data(), packets[bad])) +
                    " holds a NaN or infinite value");
            }
            batch_hits.resize(batch.size());
            accel.intersect(batch, batch_hits);
            const auto gather = [&](const PacketRows& where, HitPacket& hits) {
                gather_hits(batch_hits, static_cast<std::size_t>(&where - packets.data()), hits);
            };
            answer_chunk(chunks, packets, answers, tables, gather);
        });
    }
    return py::dict("t_hit"_a = open3d_like(t_hit), "geometry_ids"_a = open3d_like(geometry_ids),
                    "primitive_ids"_a = open3d_like(primitive_ids), "primitive_uvs"_a = open3d_like(uvs),
                    "primitive_normals"_a = open3d_like(normals));
}

py::array RaycastingScene::test_occlusions(const py::object& rays, float tnear, float tfar, int nthreads) {
    const auto rows = float_rows(rays, "rays", 6, false);
    check_threads(nthreads);
    if (std::isnan(tnear) || std::isnan(tfar) || tnear > tfar)
        throw py::value_error("tnear, tfar: expected tnear <= tfar, neither NaN");
    py::array_t<bool> result(answer_shape(rows));
    bool* out = result.mutable_data();
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kStructure);
        const Accel& accel = committed();
        for_each_ray_chunk(rows, nthreads, tnear, tfar,
                           [&](std::size_t first, const std::vector<Ray>& chunk) {
                               std::vector<std::uint8_t> occluded(chunk.size());
                               accel.occluded(chunk, occluded);
                               std::copy(occluded.begin(), occluded.end(), out + first);
                           });
    }
    return open3d_like(result);
}

py::array RaycastingScene::count_intersections(const py::object& rays, int nthreads) {
    const auto rows = float_rows(rays, "rays", 6, false);
    check_threads(nthreads);
    py::array_t<std::int32_t> counts(answer_shape(rows));
    std::int32_t* count = counts.mutable_data();
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kQueries);
        const GeometryQueries& all = queries();
        for_each_ray_chunk(rows, nthreads, 0.0f, kInfinity,
                           [&](std::size_t first, const std::vector<Ray>& chunk) {
                               std::vector<Hit> hits;
                               for (std::size_t k = 0; k < chunk.size(); ++k) {
                                   hits.clear();
                                   all.all_hits(chunk[k], hits);
                                   count[first + k] = static_cast<std::int32_t>(hits.size());
                               }
                           });
    }
    return open3d_like(counts);
}

py::dict RaycastingScene::list_intersections(const py::object& rays, int nthreads) {
    const auto rows = float_rows(rays, "rays", 6, false);
    check_threads(nthreads);
    std::vector<std::vector<Hit>> per_ray(static_cast<std::size_t>(rows.size() / 6));
    std::vector<std::pair<std::uint32_t, std::uint32_t>> ids;  // geometry and primitive of each hit, in order
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kQueries);
        const GeometryQueries& all = queries();
        for_each_ray_chunk(rows, nthreads, 0.0f, kInfinity,
                           [&](std::size_t first, const std::vector<Ray>& chunk) {
                               for (std::size_t k = 0; k < chunk.size(); ++k)
                                   all.all_hits(chunk[k], per_ray[first + k]);
                           });
        for (const std::vector<Hit>& hits : per_ray) {
            for (const Hit& hit : hits)
                ids.push_back(locate(hit.prim));
        }
    }
    const auto size = static_cast<py::ssize_t>(ids.size());
    py::array_t<std::uint32_t> ray_splits(static_cast<py::ssize_t>(per_ray.size() + 1)), ray_ids(size),
        geometry_ids(size), primitive_ids(size);
    py::array_t<float> t_hit(size), uvs(std::vector<py::ssize_t>{size, 2});
    std::size_t k = 0;
    ray_splits.mutable_data()[0] = 0;
    for (std::size_t i = 0; i < per_ray.size(); ++i) {
        for (const Hit& hit : per_ray[i]) {
            ray_ids.mutable_data()[k] = static_cast<std::uint32_t>(i);
            std::tie(geometry_ids.mutable_data()[k], primitive_ids.mutable_data()[k]) = ids[k];
            t_hit.mutable_data()[k] = hit.t;
            uvs.mutable_data()[2 * k] = hit.u;
            uvs.mutable_data()[2 * k + 1] = hit.v;
            ++k;
        }
        ray_splits.mutable_data()[i + 1] = static_cast<std::uint32_t>(k);
    }
    return py::dict("ray_splits"_a = open3d_like(ray_splits), "ray_ids"_a = open3d_like(ray_ids),
                    "geometry_ids"_a = open3d_like(geometry_ids),
                    "primitive_ids"_a = open3d_like(primitive_ids), "primitive_uvs"_a = open3d_like(uvs),
                    "t_hit"_a = open3d_like(t_hit));
}

py::dict RaycastingScene::compute_closest_points(const py::object& query_points, int nthreads) {
    const auto rows = float_rows(query_points, "query_points", 3);
    check_threads(nthreads);
    py::array_t<float> points(answer_shape(rows, {3})), uvs(answer_shape(rows, {2})),
        normals(answer_shape(rows, {3}));
    py::array_t<std::uint32_t> geometry_ids(answer_shape(rows)), primitive_ids(answer_shape(rows));
    const float* q = rows.data();
    float* point = points.mutable_data();
    float* uv = uvs.mutable_data();
    float* normal = normals.mutable_data();
    std::uint32_t* geometry = geometry_ids.mutable_data();
    std::uint32_t* primitive = primitive_ids.mutable_data();
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kQueries | kNormals);
        const GeometryQueries& all = queries();
        const NormalTable unit_normal = unit_normals();
        parallel_for(
            static_cast<std::size_t>(rows.size() / 3), kChunk, nthreads,
            [&](std::size_t first, std::size_t last) {
                for (std::size_t i = first; i < last; ++i) {
                    const NearestPoint nearest = all.nearest_point({q[3 * i], q[3 * i + 1], q[3 * i + 2]});
                    const float* n = unit_normal.xyz + 3 * static_cast<std::size_t>(nearest.prim);
                    point[3 * i] = nearest.point.x, point[3 * i + 1] = nearest.point.y,
                              point[3 * i + 2] = nearest.point.z;
                    std::copy_n(n, 3, normal + 3 * i);
                    uv[2 * i] = nearest.u, uv[2 * i + 1] = nearest.v;
                    std::tie(geometry[i], primitive[i]) = locate(nearest.prim);
                }
            });
    }
    return py::dict("points"_a = open3d_like(points), "geometry_ids"_a = open3d_like(geometry_ids),
                    "primitive_ids"_a = open3d_like(primitive_ids), "primitive_uvs"_a = open3d_like(uvs),
                    "primitive_normals"_a = open3d_like(normals));
}

bool RaycastingScene::inside(const GeometryQueries& all, const Vec3f& p,
                             std::span<const Vec3f> directions) const {
    std::size_t odd = 0;
    // One buffer a thread rather than an allocation and its growth a point.
    thread_local std::vector<Hit> hits;
    for (const Vec3f& direction : directions) {
        hits.clear();
        all.all_hits({p, direction, 0.0f, kInfinity}, hits);
        // A crossing through a shared vertex or edge is hit on each triangle that holds it, at the same t:
        // one crossing.
        std::size_t crossings = 0;
        for (std::size_t h = 0; h < hits.size(); ++h)
            crossings += (h == 0 || hits[h].t != hits[h - 1].t) ? 1 : 0;
        odd += crossings % 2;
    }
    return 2 * odd > directions.size();
}

template <class PerPoint>
py::array RaycastingScene::map_points(const py::object& query_points, int nthreads, PerPoint&& per_point) {
    const auto rows = float_rows(query_points, "query_points", 3);
    check_threads(nthreads);
    py::array_t<float> answers(answer_shape(rows));
    float* out = answers.mutable_data();
    const float* q = rows.data();
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kQueries);
        const GeometryQueries& all = queries();
        parallel_for(static_cast<std::size_t>(rows.size() / 3), kChunk, nthreads,
                     [&](std::size_t first, std::size_t last) {
                         for (std::size_t i = first; i < last; ++i)
                             out[i] = per_point(all, Vec3f(q[3 * i], q[3 * i + 1], q[3 * i + 2]));
                     });
    }
    return open3d_like(answers);
}

py::array RaycastingScene::compute_distance(const py::object& query_points, int nthreads) {
    return map_points(query_points, nthreads, [](const GeometryQueries& all, const Vec3f& p) {
        return all.nearest_point(p).distance;
    });
}

py::array RaycastingScene::compute_occupancy(const py::object& query_points, int nthreads, int nsamples) {
    check_samples(nsamples);
    const std::vector<Vec3f> directions = sample_directions(nsamples);
    return map_points(query_points, nthreads, [&](const GeometryQueries& all, const Vec3f& p) {
        return inside(all, p, directions) ? 1.0f : 0.0f;
    });
}

py::array RaycastingScene::compute_signed_distance(const py::object& query_points, int nthreads,
                                                   int nsamples) {
    check_samples(nsamples);
    const std::vector<Vec3f> directions = sample_directions(nsamples);
    return map_points(query_points, nthreads, [&](const GeometryQueries& all, const Vec3f& p) {
        const float distance = all.nearest_point(p).distance;
        return inside(all, p, directions) ? -distance : distance;
    });
}

void RaycastingScene::save_structure(const std::filesystem::path& path) {
    py::gil_scoped_release released;
    const std::shared_lock lock = prepared(kStructure);
    try {
        world_->save_structure(path);
    } catch (const StructureFileError& error) {
        throw std::invalid_argument(std::string("path: ") + error.what());
    }
}

std::unique_ptr<RaycastingScene> RaycastingScene::load_structure(const std::filesystem::path& path,
                                                                 std::optional<bool> watertight) {
    std::optional<TriangleTest> test;
    if (watertight) test = *watertight ? TriangleTest::Watertight : TriangleTest::MollerTrumbore;
    std::unique_ptr<World> world;
    {
        py::gil_scoped_release released;
        try {
            world = std::make_unique<World>(World::load_structure(path, test));
        } catch (const StructureFileError& error) {
            throw std::invalid_argument(std::string("path: ") + error.what());
        }
    }
    auto scene = std::make_unique<RaycastingScene>(
        "plucker", world->options().triangle_test == TriangleTest::Watertight, 0);
    scene->scene_ = world->scene();
    scene->first_triangle_.push_back(static_cast<std::uint32_t>(world->geometry().triangle_count()));
    scene->world_ = std::move(world);
    return scene;
}

py::dict RaycastingScene::stats() {
    AccelStats stats;
    std::size_t memory_bytes = 0;
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kStructure);
        stats = committed().stats();
        memory_bytes = committed().memory_bytes();
    }
    // The structure's own figures (`lancer stats`'), counts as ints.
    py::dict answer("accel"_a = accel_name_, "primitives"_a = stats.primitives,
                    "build_ms"_a = stats.build_ms);
    for (const AccelFigure& figure : stats.figures) {
        if (figure.whole)
            answer[figure.key.c_str()] = static_cast<std::uint64_t>(figure.value);
        else
            answer[figure.key.c_str()] = figure.value;
    }
    answer["memory_bytes"] = memory_bytes;
    return answer;
}

}  // namespace lancer::python
