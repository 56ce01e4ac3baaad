// Embree on the canonical view of shared/bench/VIEWS.md, called the way Embree's own tutorials call it and
// with no lancer code: the yardstick that `lancer bench`'s Embree rows must match (scripts/embree_check.py;
// docs/results.md, "Embree at its best"). What the tutorials and the "Performance Recommendations" of
// Embree's manual ask for:
//   - packets of 4x2 (rtcIntersect8) and 4x4 (rtcIntersect16) pixels, rays written straight into the SoA
//     packet, and the COHERENT context flag, since camera rays are coherent;
//   - flush-to-zero and denormals-are-zero set once per tracing thread;
//   - the HIGH build quality (spatial splits), or MEDIUM; the robust flag only for --watertight.
// A frame is timed as VIEWS.md says: generate every ray, trace it, store its closest hit (16 bytes).
// --animate N times, per frame of lancer's sine wave (lancer/animate.hpp, written again here: this program
// uses no lancer code), the update Embree's dynamic_scene tutorial makes: a dynamic scene of LOW quality
// whose geometry has the REFIT quality, the new vertices written into its buffer, rtcUpdateGeometryBuffer,
// rtcCommitGeometry, rtcCommitScene; then one frame of the canonical view (the first of --calls).
// --view diffuse or shadow times VIEWS.md's secondary sets instead, made here from this program's own
// canonical-view hits and traced from an array in memory, 4096 consecutive rays a task, as `lancer bench
// --view` does: rtcIntersect1/8/16 (closest hit) or rtcOccluded1/8/16 (any hit, one byte stored) on
// consecutive rays, without the COHERENT flag, as the tutorials trace secondary rays.
// --calls 1M adds the stream calls, rtcIntersect1M and rtcOccluded1M on arrays of RTCRayHit or RTCRay: a
// tile's 64 camera rays in scanline order with the COHERENT flag, as Embree's viewer_stream tutorial traces
// them, and on the secondary views streams of 256 consecutive rays (as lancer's embree_stream). --context
// coherent|incoherent sets one flag for every call instead, to measure which suits a view.
//
//   embree_reference MESH [--size 1024] [--frames 5] [--threads 1,2] [--calls 1,8,16,1M] [--quality high]
//                         [--view primary|diffuse|shadow] [--context auto|coherent|incoherent] [--watertight]
//                         [--json FILE] [--animate N]
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <xmmintrin.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

namespace {

struct Float3 {
    float x, y, z;
};
Float3 operator+(Float3 a, Float3 b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
Float3 operator-(Float3 a, Float3 b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
Float3 operator*(float s, Float3 a) {
    return {s * a.x, s * a.y, s * a.z};
}
Float3 cross(Float3 a, Float3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
float dot(Float3 a, Float3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
Float3 normalize(Float3 a) {
    return (1.0f / std::sqrt(dot(a, a))) * a;
}

struct Mesh {
    std::vector<Float3> vertices;
    std::vector<unsigned> indices;  // three per triangle
    Float3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
};

// Every mesh of the file, triangulated, in one vertex and one index array.
Mesh load_mesh(const std::string& file) {
    const aiScene* scene = aiImportFile(file.c_str(), aiProcess_Triangulate);
    if (scene == nullptr) throw std::runtime_error(file + ": " + aiGetErrorString());
    Mesh mesh;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* part = scene->mMeshes[m];
        const auto base = static_cast<unsigned>(mesh.vertices.size());
        for (unsigned v = 0; v < part->mNumVertices; ++v) {
            const Float3 p{part->mVertices[v].x, part->mVertices[v].y, part->mVertices[v].z};
            mesh.vertices.push_back(p);
            mesh.lo = {std::min(mesh.lo.x, p.x), std::min(mesh.lo.y, p.y), std::min(mesh.lo.z, p.z)};
            mesh.hi = {std::max(mesh.hi.x, p.x), std::max(mesh.hi.y, p.y), std::max(mesh.hi.z, p.z)};
        }
        for (unsigned f = 0; f < part->mNumFaces; ++f) {
            if (part->mFaces[f].mNumIndices != 3) continue;  // points and lines
            for (unsigned k = 0; k < 3; ++k)
                mesh.indices.push_back(base + part->mFaces[f].mIndices[k]);
        }
    }
    aiReleaseImport(scene);
    return mesh;
}

// VIEWS.md's camera: eye on +z at 1.05 half-diagonals over sin(fov / 2), looking at the box's centre.
struct Camera {
    Float3 eye, forward, right, up;
    float tan_half_fov = 0.0f;
    int size = 0;

    Camera(const Mesh& mesh, int side) : size(side) {
        const float fov = 45.0f * std::numbers::pi_v<float> / 180.0f;
        const Float3 centre = 0.5f * (mesh.lo + mesh.hi);
        const Float3 diagonal = mesh.hi - mesh.lo;
        const float radius =
            0.5f * std::sqrt(diagonal.x * diagonal.x + diagonal.y * diagonal.y + diagonal.z * diagonal.z);
        eye = centre + Float3{0.0f, 0.0f, 1.05f * radius / std::sin(fov / 2.0f)};
        forward = normalize(centre - eye);
        right = normalize(cross(forward, {0.0f, 1.0f, 0.0f}));
        up = cross(right, forward);
        tan_half_fov = std::tan(fov / 2.0f);
    }

    [[nodiscard]] Float3 direction(int i, int j) const {
        const float u =
            (2.0f * (static_cast<float>(i) + 0.5f) / static_cast<float>(size) - 1.0f) * tan_half_fov;
        const float v =
            (1.0f - 2.0f * (static_cast<float>(j) + 0.5f) / static_cast<float>(size)) * tan_half_fov;
        return normalize(forward + u * right + v * up);
    }
};

struct PixelHit {
    float t;
    unsigned prim;
    float u, v;
};

constexpr int kTile = 8;  // tiles of 8x8 pixels, one task per row of tiles
// The template argument and --calls value of the stream calls (rtcIntersect1M, rtcOccluded1M), beside the
// lane counts 1, 8 and 16 of the others.
constexpr int kStream = 0;

// One call: rtcIntersect1 per pixel, packets of kWidth x kHeight pixels (4x2 for 8 lanes, 4x4 for 16), or
// the tile's rays as one stream.
template <int kLanes>
void trace_tile(RTCScene scene, const Camera& camera, RTCIntersectContextFlags flags, int x0, int y0,
                std::vector<PixelHit>& hits) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = flags;
    const int size = camera.size;
    if constexpr (kLanes == kStream) {
        RTCRayHit stream[kTile * kTile];
        unsigned count = 0;
        for (int j = y0; j < std::min(size, y0 + kTile); ++j) {
            for (int i = x0; i < std::min(size, x0 + kTile); ++i, ++count) {
                const Float3 d = camera.direction(i, j);
                stream[count].ray = {camera.eye.x, camera.eye.y, camera.eye.z, 0.0f, d.x, d.y,
                                     d.z,          0.0f,         INFINITY,     ~0u,  0,   0};
                stream[count].hit.geomID = RTC_INVALID_GEOMETRY_ID;
            }
        }
        rtcIntersect1M(scene, &context, stream, count, sizeof(RTCRayHit));
        count = 0;
        for (int j = y0; j < std::min(size, y0 + kTile); ++j) {
            for (int i = x0; i < std::min(size, x0 + kTile); ++i, ++count)
                hits[static_cast<std::size_t>(j) * size + i] = {stream[count].ray.tfar,
                                                                stream[count].hit.primID, stream[count].hit.u,
                                                                stream[count].hit.v};
        }
    } else if constexpr (kLanes == 1) {
        for (int j = y0; j < std::min(size, y0 + kTile); ++j) {
            for (int i = x0; i < std::min(size, x0 + kTile); ++i) {
                const Float3 d = camera.direction(i, j);
                RTCRayHit query;
                query.ray = {camera.eye.x, camera.eye.y, camera.eye.z, 0.0f, d.x, d.y,
                             d.z,          0.0f,         INFINITY,     ~0u,  0,   0};
                query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                rtcIntersect1(scene, &context, &query);
                hits[static_cast<std::size_t>(j) * size + i] = {query.ray.tfar, query.hit.primID, query.hit.u,
                                                                query.hit.v};
            }
        }
    } else {
        constexpr int kWidth = 4, kHeight = kLanes / 4;
        for (int py = y0; py < std::min(size, y0 + kTile); py += kHeight) {
            for (int px = x0; px < std::min(size, x0 + kTile); px += kWidth) {
                alignas(64) RTCRayHitNt<kLanes> packet;
                alignas(64) int valid[kLanes];
                for (int lane = 0; lane < kLanes; ++lane) {
                    const int i = px + lane % kWidth, j = py + lane / kWidth;
                    valid[lane] = i < size && j < size ? -1 : 0;
                    const Float3 d = camera.direction(i, j);
                    packet.ray.org_x[lane] = camera.eye.x, packet.ray.org_y[lane] = camera.eye.y;
                    packet.ray.org_z[lane] = camera.eye.z;
                    packet.ray.dir_x[lane] = d.x, packet.ray.dir_y[lane] = d.y, packet.ray.dir_z[lane] = d.z;
                    packet.ray.tnear[lane] = 0.0f, packet.ray.tfar[lane] = INFINITY;
                    packet.ray.time[lane] = 0.0f, packet.ray.mask[lane] = ~0u;
                    packet.ray.id[lane] = 0, packet.ray.flags[lane] = 0;
                    packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
                }
                if constexpr (kLanes == 8)
                    rtcIntersect8(valid, scene, &context, reinterpret_cast<RTCRayHit8*>(&packet));
                else
                    rtcIntersect16(valid, scene, &context, reinterpret_cast<RTCRayHit16*>(&packet));
                for (int lane = 0; lane < kLanes; ++lane) {
                    if (!valid[lane]) continue;
                    const int i = px + lane % kWidth, j = py + lane / kWidth;
                    hits[static_cast<std::size_t>(j) * size + i] = {packet.ray.tfar[lane],
                                                                    packet.hit.primID[lane],
                                                                    packet.hit.u[lane], packet.hit.v[lane]};
                }
            }
        }
    }
}

template <int kLanes>
void trace_frame(RTCScene scene, const Camera& camera, RTCIntersectContextFlags flags,
                 std::vector<PixelHit>& hits, tbb::task_arena& arena) {
    const int tiles = (camera.size + kTile - 1) / kTile;
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1), [&](const tbb::blocked_range<int>& rows) {
            // Embree's manual: set FTZ and DAZ in every thread that calls it (cheap, so once per task here).
            _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
            _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
            for (int row = rows.begin(); row < rows.end(); ++row) {
                for (int x0 = 0; x0 < camera.size; x0 += kTile)
                    trace_tile<kLanes>(scene, camera, flags, x0, row * kTile, hits);
            }
        });
    });
}

// A secondary ray of VIEWS.md.
struct SecondaryRay {
    Float3 origin, direction;
    float tfar;
};

// VIEWS.md's PCG hash (Jarzynski & Olano 2020), in wrapping uint32 arithmetic.
std::uint32_t pcg_hash(std::uint32_t x) {
    const std::uint32_t state = x * 747796405u + 2891336453u;
    const std::uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// The diffuse (4 cosine-weighted rays per hit, Duff et al. 2017's basis) or the shadow set (1 ray per hit to
// the point light c + (0.5 r, 2 r, 1.5 r), tfar = 1 - 1e-4) from the canonical view's hits, in pixel order.
std::vector<SecondaryRay> secondary_rays(const Mesh& mesh, const Camera& camera,
                                         const std::vector<PixelHit>& hits, bool diffuse) {
    const Float3 centre = 0.5f * (mesh.lo + mesh.hi);
    const Float3 diagonal = mesh.hi - mesh.lo;
    const float radius = 0.5f * std::sqrt(dot(diagonal, diagonal));
    const Float3 light = centre + Float3{0.5f * radius, 2.0f * radius, 1.5f * radius};
    std::vector<SecondaryRay> rays;
    for (int j = 0; j < camera.size; ++j) {
        for (int i = 0; i < camera.size; ++i) {
            const std::size_t pixel = static_cast<std::size_t>(j) * camera.size + i;
            const PixelHit& hit = hits[pixel];
            if (!(hit.t < INFINITY)) continue;
            const Float3 d = camera.direction(i, j);
            const Float3 v0 = mesh.vertices[mesh.indices[3 * hit.prim]];
            const Float3 v1 = mesh.vertices[mesh.indices[3 * hit.prim + 1]];
            const Float3 v2 = mesh.vertices[mesh.indices[3 * hit.prim + 2]];
            Float3 n = normalize(cross(v1 - v0, v2 - v0));
            if (dot(n, d) >= 0.0f) n = -1.0f * n;
            const Float3 origin = camera.eye + hit.t * d + (1e-4f * radius) * n;
            if (!diffuse) {
                rays.push_back({origin, light - origin, 1.0f - 1e-4f});
                continue;
            }
            const float sign = std::copysign(1.0f, n.z);
            const float a = -1.0f / (sign + n.z), b = n.x * n.y * a;
            const Float3 t1{1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x};
            const Float3 t2{b, sign + n.y * n.y * a, -n.y};
            for (std::uint32_t k = 0; k < 4; ++k) {
                const std::uint32_t ha = pcg_hash(4u * static_cast<std::uint32_t>(pixel) + k),
                                    hb = pcg_hash(ha);
                const float u1 = static_cast<float>(ha >> 8u) * 0x1p-24f,
                            u2 = static_cast<float>(hb >> 8u) * 0x1p-24f;
                const float phi = 2.0f * std::numbers::pi_v<float> * u1, rho = std::sqrt(u2);
                rays.push_back(
                    {origin, rho * std::cos(phi) * t1 + rho * std::sin(phi) * t2 + std::sqrt(1.0f - u2) * n,
                     INFINITY});
            }
        }
    }
    return rays;
}

constexpr std::size_t kChunk = 4096;      // consecutive rays a task, as lancer bench's arrays
constexpr std::size_t kStreamRays = 256;  // rays a stream call, as lancer's embree_stream (embree_rays.cpp)

// The rays [first, last) in calls of kLanes consecutive rays: closest hits into `hits` (diffuse), or
// occlusion bytes into `occluded` (shadow).
template <int kLanes>
void trace_chunk(RTCScene scene, const std::vector<SecondaryRay>& rays, RTCIntersectContextFlags flags,
                 std::size_t first, std::size_t last, bool shadow, std::vector<PixelHit>& hits,
                 std::vector<std::uint8_t>& occluded) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = flags;
    auto fill = [&](auto& ray, std::size_t index, int lane) {
        const SecondaryRay& r = rays[index];
        ray.org_x[lane] = r.origin.x, ray.org_y[lane] = r.origin.y, ray.org_z[lane] = r.origin.z;
        ray.dir_x[lane] = r.direction.x, ray.dir_y[lane] = r.direction.y, ray.dir_z[lane] = r.direction.z;
        ray.tnear[lane] = 0.0f, ray.tfar[lane] = r.tfar, ray.time[lane] = 0.0f, ray.mask[lane] = ~0u;
        ray.id[lane] = 0, ray.flags[lane] = 0;
    };
    if constexpr (kLanes == kStream) {
        // One-lane packets, laid out as RTCRay and RTCRayHit, so that `fill` writes them too.
        for (std::size_t base = first; base < last; base += kStreamRays) {
            const auto count = static_cast<unsigned>(std::min(kStreamRays, last - base));
            if (shadow) {
                alignas(16) RTCRayNt<1> stream[kStreamRays];
                for (unsigned k = 0; k < count; ++k)
                    fill(stream[k], base + k, 0);
                rtcOccluded1M(scene, &context, reinterpret_cast<RTCRay*>(stream), count, sizeof(RTCRay));
                for (unsigned k = 0; k < count; ++k)
                    occluded[base + k] = stream[k].tfar[0] == -INFINITY ? 1 : 0;
            } else {
                alignas(16) RTCRayHitNt<1> stream[kStreamRays];
                for (unsigned k = 0; k < count; ++k) {
                    fill(stream[k].ray, base + k, 0);
                    stream[k].hit.geomID[0] = RTC_INVALID_GEOMETRY_ID;
                }
                rtcIntersect1M(scene, &context, reinterpret_cast<RTCRayHit*>(stream), count,
                               sizeof(RTCRayHit));
                for (unsigned k = 0; k < count; ++k)
                    hits[base + k] = {stream[k].ray.tfar[0], stream[k].hit.primID[0], stream[k].hit.u[0],
                                      stream[k].hit.v[0]};
            }
        }
    } else {
        for (std::size_t base = first; base < last; base += kLanes) {
            alignas(64) int valid[kLanes];
            for (int lane = 0; lane < kLanes; ++lane)
                valid[lane] = base + lane < last ? -1 : 0;
            if (shadow) {
                alignas(64) RTCRayNt<kLanes> packet;
                for (int lane = 0; lane < kLanes; ++lane)
                    fill(packet, std::min(base + lane, last - 1), lane);
                if constexpr (kLanes == 1) rtcOccluded1(scene, &context, reinterpret_cast<RTCRay*>(&packet));
                if constexpr (kLanes == 8)
                    rtcOccluded8(valid, scene, &context, reinterpret_cast<RTCRay8*>(&packet));
                if constexpr (kLanes == 16)
                    rtcOccluded16(valid, scene, &context, reinterpret_cast<RTCRay16*>(&packet));
                for (int lane = 0; lane < kLanes && base + lane < last; ++lane)
                    occluded[base + lane] = packet.tfar[lane] == -INFINITY ? 1 : 0;
            } else {
                alignas(64) RTCRayHitNt<kLanes> packet;
                for (int lane = 0; lane < kLanes; ++lane) {
                    fill(packet.ray, std::min(base + lane, last - 1), lane);
                    packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
                }
                if constexpr (kLanes == 1)
                    rtcIntersect1(scene, &context, reinterpret_cast<RTCRayHit*>(&packet));
                if constexpr (kLanes == 8)
                    rtcIntersect8(valid, scene, &context, reinterpret_cast<RTCRayHit8*>(&packet));
                if constexpr (kLanes == 16)
                    rtcIntersect16(valid, scene, &context, reinterpret_cast<RTCRayHit16*>(&packet));
                for (int lane = 0; lane < kLanes && base + lane < last; ++lane)
                    hits[base + lane] = {packet.ray.tfar[lane], packet.hit.primID[lane], packet.hit.u[lane],
                                         packet.hit.v[lane]};
            }
        }
    }
}

template <int kLanes>
void trace_array(RTCScene scene, const std::vector<SecondaryRay>& rays, RTCIntersectContextFlags flags,
                 bool shadow, std::vector<PixelHit>& hits, std::vector<std::uint8_t>& occluded,
                 tbb::task_arena& arena) {
    arena.execute([&] {
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, rays.size(), kChunk),
            [&](const tbb::blocked_range<std::size_t>& range) {
                _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
                _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
                trace_chunk<kLanes>(scene, rays, flags, range.begin(), range.end(), shadow, hits, occluded);
            },
            tbb::simple_partitioner());
    });
}

// lancer's animation (lancer/animate.hpp's SineWave): y lifted by 5% of the largest extent times
// sin(2 pi (x - lo.x) / extent.x - 2 pi frame / frames), in double, rounded once.
void wave_frame(const Mesh& mesh, int frame, int frames, float* out) {
    const Float3 extent = mesh.hi - mesh.lo;
    const double lift = static_cast<double>(0.05f) * std::max({extent.x, extent.y, extent.z, 0.0f});
    const double wavenumber = extent.x > 0.0f ? 2.0 * std::numbers::pi / extent.x : 0.0;
    const double phase = 2.0 * std::numbers::pi * (frame % frames) / frames;
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
        const Float3 p = mesh.vertices[v];
        out[3 * v] = p.x;
        out[3 * v + 1] = static_cast<float>(p.y + lift * std::sin(wavenumber * (p.x - mesh.lo.x) - phase));
        out[3 * v + 2] = p.z;
    }
}

double milliseconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// --animate: per frame, Embree's refit of the moved vertices and one frame of the canonical view.
template <int kLanes>
void run_animation(const Mesh& mesh, RTCScene scene, RTCGeometry geometry, const Camera& camera, int frames,
                   int threads) {
    tbb::task_arena arena(threads);
    std::vector<PixelHit> hits(static_cast<std::size_t>(camera.size) * static_cast<std::size_t>(camera.size));
    std::vector<float> moved(3 * mesh.vertices.size());
    auto* buffer = static_cast<float*>(rtcGetGeometryBufferData(geometry, RTC_BUFFER_TYPE_VERTEX, 0));
    std::vector<double> update_ms, trace_ms, frame_ms;
    for (int frame = 1; frame <= frames; ++frame) {
        wave_frame(mesh, frame, frames, moved.data());  // the application's work, not timed
        const auto start = std::chrono::steady_clock::now();
        arena.execute([&] {
            std::copy(moved.begin(), moved.end(), buffer);
            rtcUpdateGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0);
            rtcCommitGeometry(geometry);
            rtcCommitScene(scene);
        });
        update_ms.push_back(milliseconds_since(start));
        const auto trace_start = std::chrono::steady_clock::now();
        trace_frame<kLanes>(scene, camera, RTC_INTERSECT_CONTEXT_FLAG_COHERENT, hits, arena);
        trace_ms.push_back(milliseconds_since(trace_start));
        frame_ms.push_back(update_ms.back() + trace_ms.back());
        std::printf("frame %3d threads %d: update %8.2f ms, trace %8.2f ms (rtcIntersect%s)\n", frame,
                    threads, update_ms.back(), trace_ms.back(),
                    kLanes == kStream ? "1M" : std::to_string(kLanes).c_str());
    }
    auto median = [](std::vector<double> values) {
        std::sort(values.begin(), values.end());
        return values[values.size() / 2];
    };
    std::printf("medians over %d frames, threads %d: update %.2f ms, trace %.2f ms, update + trace %.2f ms\n",
                frames, threads, median(update_ms), median(trace_ms), median(frame_ms));
    std::fflush(stdout);
}

std::vector<int> parse_list(const std::string& text) {
    std::vector<int> values;
    std::size_t start = 0;
    while (start <= text.size()) {
        const std::size_t comma = std::min(text.find(',', start), text.size());
        const std::string item = text.substr(start, comma - start);
        values.push_back(item == "1M" ? kStream : std::stoi(item));
        start = comma + 1;
    }
    return values;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app("Embree on VIEWS.md's canonical view, called as its tutorials do (no lancer code)");
    std::string file, thread_list = "1,2", call_list = "1,8,16,1M", quality = "high", view = "primary",
                      context = "auto", json_file;
    int size = 1024, frames = 5, animate = 0;
    bool watertight = false;
    app.add_option("mesh", file, "Mesh file (OBJ, OFF, PLY: read by assimp)")->required();
    app.add_option("--size", size, "Image side")->check(CLI::Range(1, 16384));
    app.add_option("--frames", frames, "Timed frames after one warm-up")->check(CLI::Range(1, 1000));
    app.add_option("--threads", thread_list, "Comma-separated thread counts");
    app.add_option("--calls", call_list,
                   "Comma-separated calls: 1 (rtcIntersect1), 8, 16, 1M (rtcIntersect1M)");
    app.add_option("--quality", quality, "Build quality")->check(CLI::IsMember({"high", "medium", "refit"}));
    app.add_option("--view", view, "VIEWS.md's view")->check(CLI::IsMember({"primary", "diffuse", "shadow"}));
    app.add_option("--context", context,
                   "The context flag of every call; auto: COHERENT on the primary view and for 8- and 16-ray "
                   "occlusion packets, INCOHERENT otherwise")
        ->check(CLI::IsMember({"auto", "coherent", "incoherent"}));
    app.add_flag("--watertight", watertight, "Embree's robust mode (RTC_SCENE_FLAG_ROBUST)");
    app.add_option("--json", json_file, "Write one record per call and thread count");
    app.add_option("--animate", animate,
                   "Frames of lancer's sine wave: time Embree's update of each (the refit quality unless "
                   "--quality says otherwise) and a trace of the canonical view")
        ->check(CLI::Range(1, 10000));
    CLI11_PARSE(app, argc, argv);
    // Embree's dynamic_scene tutorial: refitted geometry in a dynamic scene of LOW quality.
    const bool refit = quality == "refit" || (animate > 0 && app.count("--quality") == 0);
    if (refit) quality = "refit";

    const Mesh mesh = load_mesh(file);
    const std::size_t triangles = mesh.indices.size() / 3;
    const RTCDevice device = rtcNewDevice(nullptr);
    const auto build_start = std::chrono::steady_clock::now();
    const RTCScene scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, refit               ? RTC_BUILD_QUALITY_LOW
                                   : quality == "high" ? RTC_BUILD_QUALITY_HIGH
                                                       : RTC_BUILD_QUALITY_MEDIUM);
    rtcSetSceneFlags(scene, (refit ? RTC_SCENE_FLAG_DYNAMIC : RTC_SCENE_FLAG_NONE) |
                                (watertight ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE));
    const RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (refit) rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_REFIT);
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices.size()));
    std::copy_n(&mesh.vertices[0].x, 3 * mesh.vertices.size(), vertices);
    auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles));
    std::copy(mesh.indices.begin(), mesh.indices.end(), indices);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene, geometry);
    rtcCommitScene(scene);
    const double build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - build_start).count();

    const Camera camera(mesh, size);
    if (animate > 0) {
        std::printf("embree_reference --animate: %s, %zu triangles, %s build %.1f ms%s\n",
                    std::filesystem::path(file).filename().string().c_str(), triangles, quality.c_str(),
                    build_ms, watertight ? ", robust" : "");
        const int calls = parse_list(call_list).front();
        for (const int threads : parse_list(thread_list)) {
            if (calls == kStream)
                run_animation<kStream>(mesh, scene, geometry, camera, animate, threads);
            else if (calls == 16)
                run_animation<16>(mesh, scene, geometry, camera, animate, threads);
            else if (calls == 8)
                run_animation<8>(mesh, scene, geometry, camera, animate, threads);
            else
                run_animation<1>(mesh, scene, geometry, camera, animate, threads);
        }
        rtcReleaseGeometry(geometry);
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
        return 0;
    }
    rtcReleaseGeometry(geometry);
    const std::string mesh_name = std::filesystem::path(file).filename().string();
    std::vector<PixelHit> hits(static_cast<std::size_t>(size) * static_cast<std::size_t>(size));
    std::vector<SecondaryRay> secondary;
    std::vector<std::uint8_t> occluded;
    const bool primary = view == "primary", shadow = view == "shadow";
    // auto: the flag under which each call is fastest on the view (docs/results.md, "Which context flag suits
    // which view"), the one lancer's Embree rows use.
    const auto flags_of = [&](int calls) {
        const bool coherent = context == "coherent" ||
                              (context == "auto" && (primary || (shadow && (calls == 8 || calls == 16))));
        return coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    };
    if (!primary) {
        tbb::task_arena arena;
        trace_frame<1>(scene, camera, RTC_INTERSECT_CONTEXT_FLAG_COHERENT, hits, arena);
        secondary = secondary_rays(mesh, camera, hits, view == "diffuse");
        hits.assign(secondary.size(), {});
        occluded.assign(secondary.size(), 0);
    }
    std::string json = "[\n";
    std::printf("embree_reference: %s, %zu triangles, %s build %.1f ms%s\n", mesh_name.c_str(), triangles,
                quality.c_str(), build_ms, watertight ? ", robust" : "");
    for (const int calls : parse_list(call_list)) {
        if (calls != 1 && calls != 8 && calls != 16 && calls != kStream) {
            std::fprintf(stderr, "embree_reference: --calls: expected 1, 8, 16 or 1M, got %d\n", calls);
            return 2;
        }
        const RTCIntersectContextFlags flags = flags_of(calls);
        for (const int threads : parse_list(thread_list)) {
            tbb::task_arena arena(threads);
            std::vector<double> mrays;
            for (int frame = -1; frame < frames; ++frame) {  // frame -1: the warm-up
                const auto start = std::chrono::steady_clock::now();
                if (primary && calls == 1) trace_frame<1>(scene, camera, flags, hits, arena);
                if (primary && calls == 8) trace_frame<8>(scene, camera, flags, hits, arena);
                if (primary && calls == 16) trace_frame<16>(scene, camera, flags, hits, arena);
                if (primary && calls == kStream) trace_frame<kStream>(scene, camera, flags, hits, arena);
                if (!primary) {
                    if (calls == 1) trace_array<1>(scene, secondary, flags, shadow, hits, occluded, arena);
                    if (calls == 8) trace_array<8>(scene, secondary, flags, shadow, hits, occluded, arena);
                    if (calls == 16) trace_array<16>(scene, secondary, flags, shadow, hits, occluded, arena);
                    if (calls == kStream)
                        trace_array<kStream>(scene, secondary, flags, shadow, hits, occluded, arena);
                }
                const double seconds =
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                if (frame >= 0) mrays.push_back(static_cast<double>(hits.size()) / seconds * 1e-6);
            }
            std::sort(mrays.begin(), mrays.end());
            std::size_t hit_count = 0;
            if (shadow) {
                hit_count = static_cast<std::size_t>(std::count(occluded.begin(), occluded.end(), 1));
            } else {
                for (const PixelHit& hit : hits)
                    hit_count += hit.t < INFINITY ? 1 : 0;
            }
            const double median = mrays[mrays.size() / 2];
            const double hit_fraction = static_cast<double>(hit_count) / static_cast<double>(hits.size());
            const std::string call = std::string(shadow ? "rtcOccluded" : "rtcIntersect") +
                                     (calls == kStream ? "1M" : std::to_string(calls));
            std::printf("%-16s %-8s %-14s threads %d: %8.2f Mrays/s (min %.2f, max %.2f), hits %.2f%%\n",
                        mesh_name.c_str(), view.c_str(), call.c_str(), threads, median, mrays.front(),
                        mrays.back(), 100.0 * hit_fraction);
            std::fflush(stdout);
            json += std::string(json.size() > 2 ? ",\n" : "") + "  {\"mesh\": \"" + mesh_name +
                    "\", \"view\": \"" + view + "\", \"rays\": " + std::to_string(hits.size()) +
                    ", \"triangles\": " + std::to_string(triangles) + ", \"call\": \"" + call +
                    "\", \"packet\": " + std::to_string(calls == kStream ? 1 : calls) +
                    ", \"threads\": " + std::to_string(threads) +
                    ", \"build_ms\": " + std::to_string(build_ms) +
                    ", \"mrays_per_s\": " + std::to_string(median) +
                    ", \"hit_fraction\": " + std::to_string(hit_fraction) + "}";
        }
    }
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    if (!json_file.empty()) {
        std::ofstream out(json_file);
        out << json << "\n]\n";
        if (!out) {
            std::fprintf(stderr, "embree_reference: cannot write %s\n", json_file.c_str());
            return 2;
        }
    }
    return 0;
}
