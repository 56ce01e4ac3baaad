#include "raycasting_scene.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <stdexcept>

#include "array_arguments.hpp"
#include "lancer/parallel.hpp"
#include "mesh_arguments.hpp"

namespace lancer::python {

using namespace pybind11::literals;

namespace {

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
    check_accel(accel_name_);
    scene_.materials.emplace_back();  // the meshes' material 0: a World renders what it holds
}

std::uint32_t RaycastingScene::add_triangles(const py::object& vertex_positions,
                                             const py::object& triangle_indices) {
    return add_geometry(
        mesh_argument(vertex_positions, triangle_indices, "vertex_positions", "triangle_indices"),
        "triangle_indices");
}

std::uint32_t RaycastingScene::add_mesh(const py::object& mesh) {
    return add_geometry(open3d_mesh_argument(mesh), "mesh.triangle['indices']");
}

std::uint32_t RaycastingScene::add_geometry(TriangleMesh mesh, const std::string& triangles_name) {
    py::gil_scoped_release released;
    const std::unique_lock lock = lock_.writing();
    mesh.name = "geometry " + std::to_string(first_triangle_.size() - 1);
    const std::size_t total = first_triangle_.back() + mesh.triangle_count();
    if (total > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
        throw std::invalid_argument(triangles_name + ": more triangles than a hit's 32-bit id can number");
    queries_.reset();  // first: it reads the World's triangles
    unit_normals_.clear();
    if (world_) {
        scene_ = std::move(*world_).take_scene();
        world_.reset();
    }
    scene_.meshes.push_back(std::move(mesh));
    first_triangle_.push_back(static_cast<std::uint32_t>(total));
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
        const std::unique_lock lock = lock_.writing();
        const std::vector<TriangleMesh>& meshes = scene().meshes;
        if (!id.value || *id.value >= meshes.size()) {
            throw py::value_error("geometry_id: " + id.text + ", the scene has " +
                                  std::to_string(meshes.size()) + " geometries");
        }
        const auto geometry = static_cast<std::size_t>(*id.value);
        const TriangleMesh& mesh = meshes[geometry];
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
        // The structure follows (a refit for the BVHs) once built, moving the world's scene's vertices;
        // before, the next query builds it.
        if (world_) {
            queries_.reset();  // its own tree is over the triangles about to move
            unit_normals_.clear();
            building([&] { report = world_->update_vertices(geometry, positions); });
        } else {
            scene_.meshes[geometry].positions = std::move(positions);
        }
    }
    if (!report) return py::dict("method"_a = "deferred", "ms"_a = 0.0, "sah_ratio"_a = 1.0);
    return py::dict("method"_a = report->method == UpdateMethod::Refit ? "refit" : "rebuild",
                    "ms"_a = report->ms, "sah_ratio"_a = report->sah_ratio);
}

bool RaycastingScene::ready(unsigned needs) const {
    return world_ && (!(needs & kQueries) || queries_) && (!(needs & kNormals) || !unit_normals_.empty());
}

std::shared_lock<std::shared_mutex> RaycastingScene::prepared(unsigned needs) {
    return lock_.prepared([&] { return ready(needs); }, [&] { prepare(needs); });
}

void RaycastingScene::prepare(unsigned needs) {
    if (first_triangle_.back() == 0) throw std::invalid_argument("the scene is empty: add_triangles first");
    if (!world_)
        building(
            [&] { world_ = std::make_unique<World>(std::move(scene_), accel_name_, build_options(test_)); });
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
    return occlusion_answers(
        rays, tnear, tfar, nthreads, [&] { return prepared(kStructure); },
        [&](std::span<const Ray> chunk, std::span<std::uint8_t> answers) {
            committed().occluded(chunk, answers);
        });
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

std::vector<std::uint8_t> RaycastingScene::inside_points(const GeometryQueries& all, const float* points,
                                                         std::size_t count, std::span<const Vec3f> directions,
                                                         int nthreads) {
    // The rows read in place as points (x, y, z, three floats as the rows), and every pass over them in
    // parallel, into arrays left uninitialised where they are written whole: on two cores the serial passes
    // were a large share of a call (docs/python.md, "Occupancy").
    static_assert(sizeof(Vec3f) == 3 * sizeof(float) && alignof(Vec3f) == alignof(float));
    const std::span<const Vec3f> origins(reinterpret_cast<const Vec3f*>(points), count);
    const auto odd = std::make_unique_for_overwrite<std::uint16_t[]>(count);  // votes, at most 1024
    const auto crossings = std::make_unique_for_overwrite<std::uint32_t[]>(count);
    for (std::size_t d = 0; d < directions.size(); ++d) {
        all.count_crossings(directions[d], origins, {crossings.get(), count}, nthreads);
        parallel_for(count, kChunk, nthreads, [&](std::size_t first, std::size_t last) {
            for (std::size_t i = first; i < last; ++i)
                odd[i] = static_cast<std::uint16_t>((d == 0 ? 0 : odd[i]) + crossings[i] % 2);
        });
    }
    std::vector<std::uint8_t> inside(count);
    parallel_for(count, kChunk, nthreads, [&](std::size_t first, std::size_t last) {
        for (std::size_t i = first; i < last; ++i)
            inside[i] = 2 * std::size_t{odd[i]} > directions.size() ? 1 : 0;
    });
    return inside;
}

template <class PerPoint>
py::array RaycastingScene::map_points(const py::object& query_points, int nthreads,
                                      std::span<const Vec3f> directions, PerPoint&& per_point) {
    const auto rows = float_rows(query_points, "query_points", 3);
    check_threads(nthreads);
    py::array_t<float> answers(answer_shape(rows));
    float* out = answers.mutable_data();
    const float* q = rows.data();
    const auto count = static_cast<std::size_t>(rows.size() / 3);
    {
        py::gil_scoped_release released;
        const std::shared_lock lock = prepared(kQueries);
        const GeometryQueries& all = queries();
        const std::vector<std::uint8_t> inside = directions.empty()
                                                     ? std::vector<std::uint8_t>()
                                                     : inside_points(all, q, count, directions, nthreads);
        parallel_for(count, kChunk, nthreads, [&](std::size_t first, std::size_t last) {
            for (std::size_t i = first; i < last; ++i)
                out[i] = per_point(all, Vec3f(q[3 * i], q[3 * i + 1], q[3 * i + 2]),
                                   !inside.empty() && inside[i] != 0);
        });
    }
    return open3d_like(answers);
}

py::array RaycastingScene::compute_distance(const py::object& query_points, int nthreads) {
    return map_points(query_points, nthreads, {}, [](const GeometryQueries& all, const Vec3f& p, bool) {
        return all.nearest_point(p).distance;
    });
}

py::array RaycastingScene::compute_occupancy(const py::object& query_points, int nthreads, int nsamples) {
    check_samples(nsamples);
    const std::vector<Vec3f> directions = sample_directions(nsamples);
    return map_points(query_points, nthreads, directions,
                      [](const GeometryQueries&, const Vec3f&, bool inside) { return inside ? 1.0f : 0.0f; });
}

py::array RaycastingScene::compute_signed_distance(const py::object& query_points, int nthreads,
                                                   int nsamples) {
    check_samples(nsamples);
    const std::vector<Vec3f> directions = sample_directions(nsamples);
    return map_points(query_points, nthreads, directions,
                      [](const GeometryQueries& all, const Vec3f& p, bool inside) {
                          const float distance = all.nearest_point(p).distance;
                          return inside ? -distance : distance;
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
    put_figures(answer, stats.figures);
    answer["memory_bytes"] = memory_bytes;
    return answer;
}

}  // namespace lancer::python
