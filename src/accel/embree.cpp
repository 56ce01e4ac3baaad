// EmbreeAccel's scene: the device, Embree's copy of the geometry (scaled into its float range) and its build
// and update; embree_rays.cpp holds the ray calls.
#include "accel/embree.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <new>
#include <stdexcept>
#include <string>
#include <utility>

#include "accel/build_util.hpp"
#include "core/memory_limit.hpp"
#include "core/parallel.hpp"
namespace lancer {
namespace {

// Embree's float triangle test multiplies three of the scene's lengths (T = Ng . (v0 - o), Ng = e1 x e2),
// which overflows float well inside the coordinate domain (docs/numerical-contract.md, "Coordinate domain").
// Embree is therefore given the scene scaled by a power of two that brings its largest coordinate into
// [2^-20, 2^20], where those products stay in float's range; ordinary scenes lie there already (scale 1).
// Ray origins are scaled with the scene and directions are not, so Embree's t is lancer's times the scale:
// both exact, as every product by a power of two that neither overflows nor underflows.
constexpr int kEmbreeLargestExponent = 20;

float scene_scale(const Box3f& bounds) {
    const float largest = std::max(max_component(abs(bounds.lo)), max_component(abs(bounds.hi)));
    if (!(largest > 0.0f)) return 1.0f;  // an empty scene, or one that is a point at the origin
    const int exponent = std::ilogb(largest);
    if (std::abs(exponent) <= kEmbreeLargestExponent) return 1.0f;
    // The scale and its inverse stay normal floats (exponent within [-126, 126]).
    const int scale_exponent = std::clamp(
        exponent > 0 ? kEmbreeLargestExponent - 1 - exponent : -kEmbreeLargestExponent - exponent, -126, 126);
    return std::ldexp(1.0f, scale_exponent);
}

// Embree's allocations count against --max-memory (include/lancer/memory_limit.hpp) like operator new's. A
// request refused before it is made (post == false) fails the build with RTC_ERROR_OUT_OF_MEMORY; one
// reported after the fact cannot be refused, only counted. `device_bytes` (the structure's counter) follows
// what its device holds: Embree's only account of its BVH's size.
bool monitor_memory(void* device_bytes, ssize_t bytes, bool post) {
    auto& held = *static_cast<std::atomic<std::int64_t>*>(device_bytes);
    if (bytes < 0) {
        memory::subtract(static_cast<std::size_t>(-bytes));
        held -= static_cast<std::int64_t>(-bytes);
        return true;
    }
    if (!post && !memory::fits(static_cast<std::size_t>(bytes))) return false;
    memory::add(static_cast<std::size_t>(bytes));
    held += static_cast<std::int64_t>(bytes);
    return true;
}

void check(RTCDevice device, const char* what) {
    const RTCError error = rtcGetDeviceError(device);
    if (error == RTC_ERROR_OUT_OF_MEMORY) throw std::bad_alloc();
    if (error != RTC_ERROR_NONE)
        throw std::runtime_error(std::string("embree: ") + what + " failed (error " +
                                 std::to_string(static_cast<int>(error)) + ")");
}

}  // namespace

EmbreeAccel::EmbreeAccel(EmbreeCall call) : call_(call) {
    device_ = rtcNewDevice(nullptr);
    if (device_ == nullptr) throw std::runtime_error("embree: cannot create a device");
    rtcSetDeviceMemoryMonitorFunction(device_, monitor_memory, &device_bytes_);
}

std::string_view EmbreeAccel::name() const {
    switch (call_) {
        case EmbreeCall::Packet8:
            return "embree8";
        case EmbreeCall::Packet16:
            return "embree16";
        case EmbreeCall::Stream:
            return "embree_stream";
        case EmbreeCall::Single:
            break;
    }
    return "embree";
}

EmbreeAccel::~EmbreeAccel() {
    release_scene();
    rtcReleaseDevice(device_);
}

void EmbreeAccel::release_scene() {
    if (scene_ != nullptr) rtcReleaseScene(scene_);
    scene_ = nullptr;
}

namespace {

// Triangles per task when the vertex buffer is written.
constexpr std::size_t kVertexGrain = 1 << 14;

// Embree's copy of the geometry, scaled (scene_scale): three vertices per triangle, and each sphere as a
// point with its radius.
void write_vertices(const Geometry& geometry, float scale, float* vertices) {
    parallel::for_each_chunk(0, geometry.triangles.size(), kVertexGrain,
                             [&](std::size_t from, std::size_t to) {
                                 float* out = vertices + 9 * from;
                                 for (std::size_t i = from; i < to; ++i) {
                                     const Triangle& triangle = geometry.triangles[i];
                                     for (const Vec3f vertex : {triangle.v0, triangle.v1, triangle.v2}) {
                                         const Vec3f scaled = vertex * scale;
                                         *out++ = scaled.x, *out++ = scaled.y, *out++ = scaled.z;
                                     }
                                 }
                             });
}

void write_spheres(const Geometry& geometry, float scale, float* points) {
    for (std::size_t i = 0; i < geometry.spheres.size(); ++i) {
        const Vec3f center = geometry.spheres[i].center * scale;
        points[4 * i] = center.x, points[4 * i + 1] = center.y, points[4 * i + 2] = center.z;
        points[4 * i + 3] = geometry.spheres[i].radius * scale;
    }
}

}  // namespace

void EmbreeAccel::build_structure(const Geometry& geometry, const BuildOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    release_scene();
    quality_ = options.group<EmbreeOptions>().quality;
    triangle_test_ = options.triangle_test;
    triangle_count_ = static_cast<unsigned int>(geometry.triangles.size());
    scene_box_ = built_bounds().grown(geometric_tolerance(built_bounds()));
    scene_scale_ = scene_scale(built_bounds());
    primitive_count_ = geometry.size();
    buffer_bytes_ = 0;
    scene_ = rtcNewScene(device_);
    // Refit as Embree's dynamic_scene tutorial sets it up: a dynamic scene of low build quality, whose
    // geometries are refitted when their vertices change.
    const bool refit = quality_ == EmbreeQuality::Refit;
    rtcSetSceneBuildQuality(scene_, refit                             ? RTC_BUILD_QUALITY_LOW
                                    : quality_ == EmbreeQuality::High ? RTC_BUILD_QUALITY_HIGH
                                                                      : RTC_BUILD_QUALITY_MEDIUM);
    rtcSetSceneFlags(scene_, (refit ? RTC_SCENE_FLAG_DYNAMIC : RTC_SCENE_FLAG_NONE) |
                                 (options.triangle_test == TriangleTest::Watertight ? RTC_SCENE_FLAG_ROBUST
                                                                                    : RTC_SCENE_FLAG_NONE));

    if (!geometry.triangles.empty()) {
        // Embree's own buffers: it pads them for its vector loads, which a shared std::vector would not be.
        const RTCGeometry mesh = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        if (refit) rtcSetGeometryBuildQuality(mesh, RTC_BUILD_QUALITY_REFIT);
        const std::size_t vertex_count = 3 * geometry.triangles.size();
        auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
            mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertex_count));
        auto* indices = static_cast<unsigned int*>(
            rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                    3 * sizeof(unsigned int), geometry.triangles.size()));
        check(device_, "allocating the triangle buffers");
        write_vertices(geometry, scene_scale_, vertices);
        for (unsigned int i = 0; i < vertex_count; ++i)
            indices[i] = i;
        buffer_bytes_ += vertex_count * (3 * sizeof(float) + sizeof(unsigned int));
        rtcCommitGeometry(mesh);
        rtcAttachGeometryByID(scene_, mesh, kEmbreeTriangleGeometry);
        rtcReleaseGeometry(mesh);
    }
    if (!geometry.spheres.empty()) {
        const RTCGeometry spheres = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
        if (refit) rtcSetGeometryBuildQuality(spheres, RTC_BUILD_QUALITY_REFIT);
        auto* points =
            static_cast<float*>(rtcSetNewGeometryBuffer(spheres, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                                        4 * sizeof(float), geometry.spheres.size()));
        check(device_, "allocating the sphere buffer");
        write_spheres(geometry, scene_scale_, points);
        buffer_bytes_ += geometry.spheres.size() * 4 * sizeof(float);
        rtcCommitGeometry(spheres);
        rtcAttachGeometryByID(scene_, spheres, kEmbreeSphereGeometry);
        rtcReleaseGeometry(spheres);
    }
    rtcCommitScene(scene_);
    check(device_, "building the scene");
    build_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

UpdateReport EmbreeAccel::update_structure(const Geometry& geometry) {
    scene_box_ = built_bounds().grown(geometric_tolerance(built_bounds()));
    if (scene_scale(built_bounds()) != scene_scale_) {
        // The scale the scene's copy was made with no longer fits its coordinates: a new copy.
        BuildOptions options = build_options(triangle_test_);
        options.group<EmbreeOptions>().quality = quality_;
        build_structure(geometry, options);
        return {};
    }
    // Embree's way to move vertices: rewrite the buffers, mark them changed, commit. With the refit quality
    // Embree refits its BVH, otherwise it rebuilds it.
    const std::pair<unsigned int, bool> parts[] = {{kEmbreeTriangleGeometry, !geometry.triangles.empty()},
                                                   {kEmbreeSphereGeometry, !geometry.spheres.empty()}};
    for (const auto& [id, present] : parts) {
        if (!present) continue;
        const RTCGeometry part = rtcGetGeometry(scene_, id);
        auto* data = static_cast<float*>(rtcGetGeometryBufferData(part, RTC_BUFFER_TYPE_VERTEX, 0));
        if (id == kEmbreeTriangleGeometry) {
            write_vertices(geometry, scene_scale_, data);
        } else {
            write_spheres(geometry, scene_scale_, data);
        }
        rtcUpdateGeometryBuffer(part, RTC_BUFFER_TYPE_VERTEX, 0);
        rtcCommitGeometry(part);
    }
    rtcCommitScene(scene_);
    check(device_, "updating the scene");
    return {.method = update_method()};
}

AccelStats EmbreeAccel::stats() const {
    AccelStats stats;
    stats.build_ms = build_ms_;
    stats.primitives = primitive_count_;
    const std::size_t held = memory_bytes();
    stats.memory_by_array = {{"embree bvh and internal arrays", held - std::min(held, buffer_bytes_)},
                             {"embree buffers", buffer_bytes_}};
    return stats;
}

std::size_t EmbreeAccel::memory_bytes() const {
    // The buffers are Embree's own copies of the geometry, allocated by the device (rtcSetNewGeometryBuffer),
    // so the device's count holds them; it is never below them.
    return std::max(static_cast<std::size_t>(std::max<std::int64_t>(device_bytes_.load(), 0)), buffer_bytes_);
}

std::vector<BuildOptionRow> EmbreeAccel::option_rows() {
    return {choice_option<EmbreeOptions, EmbreeQuality>(
        "quality",
        "Embree's build quality; refit: a dynamic scene whose updates Embree refits (its robust mode, the "
        "watertight test, builds without spatial splits)",
        &EmbreeOptions::quality,
        {{"high", EmbreeQuality::High}, {"medium", EmbreeQuality::Medium}, {"refit", EmbreeQuality::Refit}})};
}

}  // namespace lancer
