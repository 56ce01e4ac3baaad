// lancer bench --instances N (bench_instances.hpp): the instanced scene, its views, lancer's rows and
// Embree's.
#include "bench_instances.hpp"

#include <fmt/core.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "common.hpp"
#include "lancer/camera.hpp"
#include "lancer/generate.hpp"
#include "lancer/instances.hpp"
#include "lancer/parallel.hpp"
#include "lancer/views.hpp"

#if LANCER_HAS_EMBREE
#include <embree3/rtcore.h>

#include "lancer/denormals.hpp"
#endif

namespace lancer::cli {
namespace {

// Rays per task, as intersect_parallel's.
constexpr std::size_t kRayChunk = 4096;

// The primary view's rays in the order of the bench's tiles (8x8, in 4x4 blocks: lancer/camera.hpp), so that
// every 16 consecutive rays are a 4x4 pixel block, every 8 a 4x2 one.
std::vector<Ray> primary_rays(const PinholeCamera& camera, int size) {
    std::vector<Ray> rays;
    rays.reserve(static_cast<std::size_t>(size) * static_cast<std::size_t>(size));
    constexpr int kTile = PinholeCamera::kTileSide;
    for (int y0 = 0; y0 < size; y0 += kTile) {
        for (int x0 = 0; x0 < size; x0 += kTile) {
            for (int lane = 0; lane < kTile * kTile; ++lane) {
                const int x = x0 + PinholeCamera::tile_column(lane), y = y0 + PinholeCamera::tile_row(lane);
                if (x < size && y < size)
                    rays.push_back(
                        camera.generate(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f));
            }
        }
    }
    return rays;
}

// VIEWS.md's secondary rays from the instanced scene's primary hits: secondary_view_rays reads each hit's
// triangle and the scene's box from a Geometry, so it is given the hit triangles in the world, one per hit,
// and two points spanning the scene's box.
std::vector<Ray> secondary_rays(SecondaryView view, const InstancedScene& scene,
                                const std::vector<std::vector<Triangle>>& objects,
                                std::span<const Ray> primary, std::span<const InstanceHit> hits) {
    std::vector<Triangle> triangles;
    std::vector<Hit> flat_hits(hits.size());
    for (std::size_t i = 0; i < hits.size(); ++i) {
        if (!hits[i].hit()) continue;
        const Triangle& local =
            objects[static_cast<std::size_t>(hits[i].object)][static_cast<std::size_t>(hits[i].prim)];
        const Transform& transform = scene.transform(static_cast<std::uint32_t>(hits[i].instance));
        flat_hits[i] = {hits[i].t, static_cast<std::int32_t>(triangles.size()), hits[i].u, hits[i].v};
        triangles.push_back(
            {transform.point(local.v0), transform.point(local.v1), transform.point(local.v2)});
    }
    const Box3f box = scene.bounds();
    triangles.push_back({box.lo, box.lo, box.lo});
    triangles.push_back({box.hi, box.hi, box.hi});
    return secondary_view_rays(view, Geometry{triangles, {}}, primary, flat_hits);
}

double median_of_frames(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    return values[values.size() / 2];
}

double peak_rss_mb() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

// One way of tracing the instanced scene: lancer's InstancedScene over one object structure, or one of
// Embree's calls on its two-level scene.
class InstancedTracer {
  public:
    virtual ~InstancedTracer() = default;
    [[nodiscard]] virtual std::string name() const = 0;
    // Closest hits, or any hits, of `rays` on the threads of the caller's run_with_threads.
    virtual void intersect(std::span<const Ray> rays, std::span<InstanceHit> hits) const = 0;
    virtual void occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded) const = 0;
    // Moves every instance to `placements` and brings the structure up to date.
    virtual void move(std::span<const Transform> placements) = 0;
    [[nodiscard]] virtual std::size_t memory_bytes() const = 0;
};

class LancerTracer final : public InstancedTracer {
  public:
    LancerTracer(std::string name, InstancedScene scene, std::size_t object_bytes)
        : name_(std::move(name)), scene_(std::move(scene)), object_bytes_(object_bytes) {}
    [[nodiscard]] std::string name() const override { return name_; }
    void intersect(std::span<const Ray> rays, std::span<InstanceHit> hits) const override {
        intersect_parallel(scene_, rays, hits);
    }
    void occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded) const override {
        occluded_parallel(scene_, rays, occluded);
    }
    void move(std::span<const Transform> placements) override {
        for (std::size_t i = 0; i < placements.size(); ++i)
            scene_.set_transform(static_cast<std::uint32_t>(i), placements[i]);
        static_cast<void>(scene_.commit());
    }
    [[nodiscard]] std::size_t memory_bytes() const override { return object_bytes_ + scene_.memory_bytes(); }
    [[nodiscard]] const InstancedScene& scene() const { return scene_; }

  private:
    std::string name_;
    InstancedScene scene_;
    std::size_t object_bytes_;
};

#if LANCER_HAS_EMBREE
enum class EmbreeCall { Single, Packet8, Packet16, Stream };

// Embree's two-level scene, as its tutorials build one (tutorials/instanced_geometry): one committed scene
// with the mesh, and a scene of RTC_GEOMETRY_TYPE_INSTANCE geometries over it, each with its transform
// (rtcSetGeometryTransform, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, the Transform's layout). Robust mode with the
// watertight test, as the rest of the bench.
class EmbreeScenes {
  public:
    EmbreeScenes(const std::vector<Triangle>& triangles, std::span<const Transform> placements, bool robust) {
        device_ = rtcNewDevice(nullptr);
        rtcSetDeviceMemoryMonitorFunction(
            device_,
            [](void* counter, ssize_t bytes, bool) {
                *static_cast<std::atomic<std::int64_t>*>(counter) += bytes;
                return true;
            },
            &bytes_);
        const RTCSceneFlags flags = robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE;
        object_ = rtcNewScene(device_);
        rtcSetSceneFlags(object_, flags);
        const RTCGeometry mesh = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
            mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * triangles.size()));
        auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
            mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles.size()));
        for (std::size_t i = 0; i < triangles.size(); ++i) {
            const Triangle& t = triangles[i];
            const float values[9] = {t.v0.x, t.v0.y, t.v0.z, t.v1.x, t.v1.y, t.v1.z, t.v2.x, t.v2.y, t.v2.z};
            std::copy(values, values + 9, vertices + 9 * i);
            for (unsigned k = 0; k < 3; ++k)
                indices[3 * i + k] = static_cast<unsigned>(3 * i + k);
        }
        rtcCommitGeometry(mesh);
        rtcAttachGeometry(object_, mesh);
        rtcReleaseGeometry(mesh);
        rtcCommitScene(object_);
        top_ = rtcNewScene(device_);
        rtcSetSceneFlags(top_, flags);
        for (std::size_t i = 0; i < placements.size(); ++i) {
            const RTCGeometry instance = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(instance, object_);
            rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, &placements[i].m[0][0]);
            rtcCommitGeometry(instance);
            rtcAttachGeometryByID(top_, instance, static_cast<unsigned>(i));
            rtcReleaseGeometry(instance);
        }
        rtcCommitScene(top_);
        if (rtcGetDeviceError(device_) != RTC_ERROR_NONE) throw std::runtime_error("embree: building failed");
    }
    ~EmbreeScenes() {
        rtcReleaseScene(top_);
        rtcReleaseScene(object_);
        rtcReleaseDevice(device_);
    }
    EmbreeScenes(const EmbreeScenes&) = delete;
    EmbreeScenes& operator=(const EmbreeScenes&) = delete;

    // rtcSetGeometryTransform on each instance, rtcCommitGeometry, and one rtcCommitScene.
    void move(std::span<const Transform> placements) {
        for (std::size_t i = 0; i < placements.size(); ++i) {
            const RTCGeometry instance = rtcGetGeometry(top_, static_cast<unsigned>(i));
            rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, &placements[i].m[0][0]);
            rtcCommitGeometry(instance);
        }
        rtcCommitScene(top_);
    }
    [[nodiscard]] RTCScene top() const { return top_; }
    [[nodiscard]] std::size_t bytes() const { return static_cast<std::size_t>(bytes_.load()); }

  private:
    RTCDevice device_ = nullptr;
    RTCScene object_ = nullptr, top_ = nullptr;
    std::atomic<std::int64_t> bytes_{0};
};

// Embree's N-ray calls, N = 8 or 16.
template <int N>
struct EmbreePacket {
    static_assert(N == 8 || N == 16);
    using RayHit = std::conditional_t<N == 8, RTCRayHit8, RTCRayHit16>;
    using Ray = std::conditional_t<N == 8, RTCRay8, RTCRay16>;
    static void intersect(const int* valid, RTCScene scene, RTCIntersectContext* context, RayHit* packet) {
        if constexpr (N == 8) {
            rtcIntersect8(valid, scene, context, packet);
        } else {
            rtcIntersect16(valid, scene, context, packet);
        }
    }
    static void occluded(const int* valid, RTCScene scene, RTCIntersectContext* context, Ray* packet) {
        if constexpr (N == 8) {
            rtcOccluded8(valid, scene, context, packet);
        } else {
            rtcOccluded16(valid, scene, context, packet);
        }
    }
};

RTCRay embree_ray(const Ray& ray) {
    RTCRay out{};
    out.org_x = ray.origin.x, out.org_y = ray.origin.y, out.org_z = ray.origin.z;
    out.dir_x = ray.direction.x, out.dir_y = ray.direction.y, out.dir_z = ray.direction.z;
    out.tnear = ray.tnear, out.tfar = ray.tfar;
    out.mask = 0xffffffffu, out.flags = 0;
    return out;
}

InstanceHit lancer_hit(const RTCRayHit& record) {
    if (record.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {};
    return {record.ray.tfar, static_cast<std::int32_t>(record.hit.primID),    record.hit.u,
            record.hit.v,    static_cast<std::int32_t>(record.hit.instID[0]), 0};
}

class EmbreeTracer final : public InstancedTracer {
  public:
    EmbreeTracer(std::string name, EmbreeCall call, std::shared_ptr<EmbreeScenes> scenes)
        : name_(std::move(name)), call_(call), scenes_(std::move(scenes)) {}
    [[nodiscard]] std::string name() const override { return name_; }
    // The rays in tasks of kRayChunk; within a task, one call per ray, per 8 or 16 consecutive rays, or per
    // stream of 256, under the INCOHERENT context flag on every view: on this two-level scene COHERENT, the
    // flag the flat bench gives its primary packets, made the primary view 0.55-0.65 times as fast
    // (docs/accel/instances.md) and hangs rtcOccluded16 (Debian's Embree 3.13.5, AVX2).
    void intersect(std::span<const Ray> rays, std::span<InstanceHit> hits) const override {
        parallel_for(rays.size(), kRayChunk, 0, [&](std::size_t from, std::size_t to) {
            const DenormalsFlushed flushed;
            RTCIntersectContext context;
            rtcInitIntersectContext(&context);
            context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
            if (call_ == EmbreeCall::Packet8) return packets<8>(rays, hits, from, to, context);
            if (call_ == EmbreeCall::Packet16) return packets<16>(rays, hits, from, to, context);
            streams<false>(rays, from, to, context,
                           [&](std::size_t i, const RTCRayHit& record) { hits[i] = lancer_hit(record); });
        });
    }
    void occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded) const override {
        parallel_for(rays.size(), kRayChunk, 0, [&](std::size_t from, std::size_t to) {
            const DenormalsFlushed flushed;
            RTCIntersectContext context;
            rtcInitIntersectContext(&context);
            context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
            if (call_ == EmbreeCall::Packet8) return occluded_packets<8>(rays, occluded, from, to, context);
            if (call_ == EmbreeCall::Packet16) return occluded_packets<16>(rays, occluded, from, to, context);
            // Embree's tfar = -inf on a hit.
            streams<true>(rays, from, to, context, [&](std::size_t i, const RTCRay& record) {
                occluded[i] = record.tfar < 0.0f ? 1 : 0;
            });
        });
    }
    void move(std::span<const Transform> placements) override { scenes_->move(placements); }
    [[nodiscard]] std::size_t memory_bytes() const override { return scenes_->bytes(); }

  private:
    // Rays `from` to `to` one call per ray (rtcIntersect1, rtcOccluded1) or per stream of 256 consecutive
    // rays (rtcIntersect1M, rtcOccluded1M), then answer(index, record) for each.
    template <bool kOcclusion, class Answer>
    void streams(std::span<const Ray> rays, std::size_t from, std::size_t to, RTCIntersectContext& context,
                 Answer&& answer) const {
        using Record = std::conditional_t<kOcclusion, RTCRay, RTCRayHit>;
        constexpr std::size_t kStream = 256;
        Record stream[kStream];
        for (std::size_t first = from; first < to; first += kStream) {
            const std::size_t count = std::min(kStream, to - first);
            for (std::size_t i = 0; i < count; ++i) {
                if constexpr (kOcclusion) {
                    stream[i] = embree_ray(rays[first + i]);
                } else {
                    stream[i].ray = embree_ray(rays[first + i]);
                    stream[i].hit.geomID = RTC_INVALID_GEOMETRY_ID;
                    stream[i].hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                }
            }
            if (call_ == EmbreeCall::Stream) {
                if constexpr (kOcclusion)
                    rtcOccluded1M(scenes_->top(), &context, stream, static_cast<unsigned>(count),
                                  sizeof(Record));
                else
                    rtcIntersect1M(scenes_->top(), &context, stream, static_cast<unsigned>(count),
                                   sizeof(Record));
            } else {
                for (std::size_t i = 0; i < count; ++i) {
                    if constexpr (kOcclusion)
                        rtcOccluded1(scenes_->top(), &context, &stream[i]);
                    else
                        rtcIntersect1(scenes_->top(), &context, &stream[i]);
                }
            }
            for (std::size_t i = 0; i < count; ++i)
                answer(first + i, stream[i]);
        }
    }
    template <int N>
    void packets(std::span<const Ray> rays, std::span<InstanceHit> hits, std::size_t from, std::size_t to,
                 RTCIntersectContext& context) const {
        using Packet = EmbreePacket<N>;
        alignas(64) typename Packet::RayHit packet;
        alignas(64) int valid[N];
        for (std::size_t first = from; first < to; first += N) {
            const std::size_t count = std::min<std::size_t>(N, to - first);
            for (int lane = 0; lane < N; ++lane) {
                valid[lane] = static_cast<std::size_t>(lane) < count ? -1 : 0;
                const Ray& ray =
                    rays[first + std::min<std::size_t>(static_cast<std::size_t>(lane), count - 1)];
                packet.ray.org_x[lane] = ray.origin.x, packet.ray.org_y[lane] = ray.origin.y;
                packet.ray.org_z[lane] = ray.origin.z, packet.ray.dir_x[lane] = ray.direction.x;
                packet.ray.dir_y[lane] = ray.direction.y, packet.ray.dir_z[lane] = ray.direction.z;
                packet.ray.tnear[lane] = ray.tnear, packet.ray.tfar[lane] = ray.tfar;
                packet.ray.mask[lane] = 0xffffffffu, packet.ray.flags[lane] = 0;
                packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
                packet.hit.instID[0][lane] = RTC_INVALID_GEOMETRY_ID;
            }
            Packet::intersect(valid, scenes_->top(), &context, &packet);
            for (std::size_t lane = 0; lane < count; ++lane) {
                hits[first + lane] = packet.hit.geomID[lane] == RTC_INVALID_GEOMETRY_ID
                                         ? InstanceHit{}
                                         : InstanceHit{packet.ray.tfar[lane],
                                                       static_cast<std::int32_t>(packet.hit.primID[lane]),
                                                       packet.hit.u[lane],
                                                       packet.hit.v[lane],
                                                       static_cast<std::int32_t>(packet.hit.instID[0][lane]),
                                                       0};
            }
        }
    }
    template <int N>
    void occluded_packets(std::span<const Ray> rays, std::span<std::uint8_t> occluded, std::size_t from,
                          std::size_t to, RTCIntersectContext& context) const {
        using Packet = EmbreePacket<N>;
        alignas(64) typename Packet::Ray packet;
        alignas(64) int valid[N];
        for (std::size_t first = from; first < to; first += N) {
            const std::size_t count = std::min<std::size_t>(N, to - first);
            for (int lane = 0; lane < N; ++lane) {
                valid[lane] = static_cast<std::size_t>(lane) < count ? -1 : 0;
                const Ray& ray =
                    rays[first + std::min<std::size_t>(static_cast<std::size_t>(lane), count - 1)];
                packet.org_x[lane] = ray.origin.x, packet.org_y[lane] = ray.origin.y;
                packet.org_z[lane] = ray.origin.z, packet.dir_x[lane] = ray.direction.x;
                packet.dir_y[lane] = ray.direction.y, packet.dir_z[lane] = ray.direction.z;
                packet.tnear[lane] = ray.tnear, packet.tfar[lane] = ray.tfar;
                packet.mask[lane] = 0xffffffffu, packet.flags[lane] = 0;
            }
            Packet::occluded(valid, scenes_->top(), &context, &packet);
            for (std::size_t lane = 0; lane < count; ++lane)
                occluded[first + lane] = packet.tfar[lane] < 0.0f ? 1 : 0;
        }
    }

    std::string name_;
    EmbreeCall call_;
    std::shared_ptr<EmbreeScenes> scenes_;
};
#endif

// Rays on which `answers` differ from `reference`: another instance or primitive, or t off by more than
// 2^-16 of itself (Embree's float transform and triangle test round otherwise than lancer's).
std::size_t count_differences(std::span<const InstanceHit> reference, std::span<const InstanceHit> answers) {
    std::size_t differences = 0;
    for (std::size_t i = 0; i < reference.size(); ++i) {
        const InstanceHit &a = reference[i], &b = answers[i];
        if (a.hit() != b.hit()) {
            ++differences;
        } else if (a.hit() && (a.instance != b.instance || a.prim != b.prim ||
                               std::fabs(a.t - b.t) > 0x1p-16f * std::fabs(a.t))) {
            ++differences;
        }
    }
    return differences;
}

}  // namespace

void run_instances_bench(const std::string& mesh_name, const Scene& mesh,
                         const InstancesBenchOptions& options) {
    std::vector<std::vector<Triangle>> objects(1);
    TriangleMesh merged;
    for (const TriangleMesh& part : mesh.meshes)
        part.append_triangles(objects[0]);
    if (objects[0].empty()) throw InputError(mesh_name + ": --instances needs a mesh with triangles");
    for (const Triangle& t : objects[0]) {
        for (const Vec3f& p : {t.v0, t.v1, t.v2}) {
            merged.indices.push_back(static_cast<std::uint32_t>(merged.positions.size()));
            merged.positions.push_back(p);
        }
    }
    Box3f mesh_box;
    for (const Triangle& t : objects[0])
        mesh_box.extend(t.bounds());
    const std::vector<Transform> placements = random_placements(mesh_box, options.instances);
    fmt::print("lancer bench --instances {}: {} ({} triangles) placed {} times: {:.3g} instanced triangles\n",
               options.instances, mesh_name, objects[0].size(), options.instances,
               static_cast<double>(objects[0].size()) * options.instances);

    // Every tracer built before any is timed, as the bench's structures.
    std::vector<std::unique_ptr<InstancedTracer>> tracers;
    const LancerTracer* first_lancer = nullptr;
#if LANCER_HAS_EMBREE
    std::shared_ptr<EmbreeScenes> embree;
#endif
    fmt::print("{:<14} {:>12} {:>14} {:>12} {:>12}\n", "accel", "object ms", "top level ms", "MB",
               "peak RSS MB");
    for (const std::string& name : options.accels) {
        if (name.starts_with("embree")) {
#if LANCER_HAS_EMBREE
            const auto calls = {std::pair{"embree", EmbreeCall::Single},
                                {"embree8", EmbreeCall::Packet8},
                                {"embree16", EmbreeCall::Packet16},
                                {"embree_stream", EmbreeCall::Stream}};
            const auto call =
                std::find_if(calls.begin(), calls.end(), [&](const auto& c) { return name == c.first; });
            if (call == calls.end()) throw InputError("--accel: unknown Embree call '" + name + "'");
            if (embree == nullptr) {
                Stopwatch watch;
                embree = std::make_shared<EmbreeScenes>(objects[0], placements, options.watertight);
                fmt::print("{:<14} {:>12} {:>14.1f} {:>12.1f} {:>12.0f}\n", "embree (both)", "-",
                           watch.elapsed_ms(), static_cast<double>(embree->bytes()) / 1048576.0,
                           peak_rss_mb());
            }
            tracers.push_back(std::make_unique<EmbreeTracer>(name, call->second, embree));
            continue;
#else
            throw InputError("--accel " + name + ": this lancer was built without Embree");
#endif
        }
        AccelChoice choice{name, options.watertight, options.settings};
        Stopwatch object_watch;
        const BuildOptions build = choice.build_options();
        std::shared_ptr<Accel> object = make_accel(name);
        object->build(Geometry{objects[0], {}}, build);
        const double object_ms = object_watch.elapsed_ms();
        Stopwatch top_watch;
        InstancedScene scene(build);
        scene.add_object(object);
        for (const Transform& placement : placements)
            scene.add_instance(0, placement);
        static_cast<void>(scene.commit());
        const double top_ms = top_watch.elapsed_ms();
        auto tracer = std::make_unique<LancerTracer>(name, std::move(scene), object->memory_bytes());
        fmt::print("{:<14} {:>12.1f} {:>14.1f} {:>12.1f} {:>12.0f}\n", name, object_ms, top_ms,
                   static_cast<double>(tracer->memory_bytes()) / 1048576.0, peak_rss_mb());
        for (const auto& [array, bytes] : tracer->scene().stats().memory_by_array)
            fmt::print("  {:<22} {:>10.1f} MB\n", array, static_cast<double>(bytes) / 1048576.0);
        fmt::print("  {:<22} {:>10.1f} MB\n", "object (" + name + ")",
                   static_cast<double>(object->memory_bytes()) / 1048576.0);
        if (first_lancer == nullptr) first_lancer = tracer.get();
        tracers.push_back(std::move(tracer));
    }
    if (first_lancer == nullptr)
        throw InputError("--instances: --accel needs a lancer structure for the objects");

    // The views, from the first lancer tracer's hits.
    const PinholeCamera camera(canonical_view(first_lancer->scene().bounds(), options.size, options.size));
    const std::vector<Ray> primary = primary_rays(camera, options.size);
    std::vector<InstanceHit> primary_hits(primary.size());
    first_lancer->intersect(primary, primary_hits);
    bool disagreement = false;
    fmt::print("{:<8} {:>9} {:<14} {:>3} {:>9} {:>9} {:>9} {:>7} {:>10}\n", "view", "rays", "accel", "thr",
               "Mrays/s", "min", "max", "hits", "differ");
    for (const BenchView view : options.views) {
        std::vector<Ray> rays =
            view == BenchView::Primary
                ? primary
                : secondary_rays(view == BenchView::Diffuse ? SecondaryView::Diffuse : SecondaryView::Shadow,
                                 first_lancer->scene(), objects, primary, primary_hits);
        const bool shadow = view == BenchView::Shadow;
        std::vector<InstanceHit> reference(rays.size());
        first_lancer->intersect(rays, reference);
        std::vector<std::vector<InstanceHit>> hits(tracers.size(), std::vector<InstanceHit>(rays.size()));
        std::vector<std::vector<std::uint8_t>> occluded(tracers.size(),
                                                        std::vector<std::uint8_t>(rays.size()));
        std::vector<std::size_t> differences(tracers.size(), 0), answered(tracers.size(), 0);
        for (std::size_t k = 0; k < tracers.size(); ++k) {
            if (shadow) {
                tracers[k]->occluded(rays, occluded[k]);
                for (std::size_t i = 0; i < rays.size(); ++i) {
                    differences[k] += (occluded[k][i] != 0) != reference[i].hit() ? 1 : 0;
                    answered[k] += occluded[k][i];
                }
            } else {
                tracers[k]->intersect(rays, hits[k]);
                differences[k] = count_differences(reference, hits[k]);
                answered[k] = static_cast<std::size_t>(std::count_if(
                    hits[k].begin(), hits[k].end(), [](const InstanceHit& h) { return h.hit(); }));
            }
            // lancer's structures answer alike bit for bit; Embree rounds its own way and is kept with its
            // count.
            if (differences[k] > 0 && !tracers[k]->name().starts_with("embree")) disagreement = true;
        }
        for (const int threads : options.thread_counts) {
            std::vector<std::vector<double>> mrays(tracers.size());
            run_with_threads(threads, [&] {
                for (int frame = -1; frame < options.frames; ++frame) {
                    for (std::size_t k = 0; k < tracers.size(); ++k) {
                        Stopwatch watch;
                        if (shadow) {
                            tracers[k]->occluded(rays, occluded[k]);
                        } else {
                            tracers[k]->intersect(rays, hits[k]);
                        }
                        if (frame >= 0)
                            mrays[k].push_back(static_cast<double>(rays.size()) / (watch.elapsed_ms() * 1e3));
                    }
                }
            });
            for (std::size_t k = 0; k < tracers.size(); ++k) {
                std::sort(mrays[k].begin(), mrays[k].end());
                fmt::print("{:<8} {:>9} {:<14} {:>3} {:>9.2f} {:>9.2f} {:>9.2f} {:>6.1f}% {:>10}\n",
                           view_name(view), rays.size(), tracers[k]->name(), threads,
                           median_of_frames(mrays[k]), mrays[k].front(), mrays[k].back(),
                           100.0 * static_cast<double>(answered[k]) / static_cast<double>(rays.size()),
                           differences[k]);
                std::fflush(stdout);
            }
        }
    }

    // The top level's update: every instance moved by a small rigid step (a rotation about its own axis and a
    // translation of a tenth of the mesh), then the structure brought up to date; the median of the frames.
    fmt::print("{:<14} {:>3} {:>16}   ({} instances moved per frame, median of {} frames)\n", "accel", "thr",
               "update ms", options.instances, options.frames);
    const float step = 0.1f * max_component(mesh_box.extent());
    for (const int threads : options.thread_counts) {
        for (const auto& tracer : tracers) {
            std::vector<double> update_ms;
            std::vector<Transform> moved = placements;
            run_with_threads(threads, [&] {
                for (int frame = 0; frame < options.frames; ++frame) {
                    const float phase = 0.1f * static_cast<float>(frame + 1);
                    for (std::size_t i = 0; i < moved.size(); ++i) {
                        moved[i] = Transform::translation({step * std::sin(phase + static_cast<float>(i)),
                                                           0.0f, step * std::cos(phase)}) *
                                   placements[i] * Transform::rotation({0.0f, 1.0f, 0.0f}, phase);
                    }
                    Stopwatch watch;
                    tracer->move(moved);
                    update_ms.push_back(watch.elapsed_ms());
                }
            });
            fmt::print("{:<14} {:>3} {:>16.3f}\n", tracer->name(), threads, median_of_frames(update_ms));
        }
    }
    fmt::print("peak RSS {:.0f} MB\n", peak_rss_mb());
    if (disagreement)
        throw CheckFailure("bench: lancer's structures disagree on the instanced scene (see above)");
}

}  // namespace lancer::cli
