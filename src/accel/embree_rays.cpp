// EmbreeAccel's ray calls: lancer's rays converted into Embree's domain and packets, traced, and the hits
// converted back into lancer's numbering and intervals; embree.cpp holds the scene. Every call runs with
// flush-to-zero and denormals-are-zero (lancer/denormals.hpp), the mode Embree's manual asks for: without it
// a denormal can make its triangle test report a hit at t = NaN, on which the next geometry's traversal
// asserts `ray.valid()` and aborts. A call sets it for its duration, unless its caller has already.
#include "accel/embree.hpp"

#if defined(__AVX2__)
#include <immintrin.h>
#endif
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "accel/build_util.hpp"
#include "accel/simd_float.hpp"
#include "core/intersect.hpp"
#include "lancer/denormals.hpp"

namespace lancer {
namespace {

// Embree asserts that coordinates stay below FLT_LARGE (1.8e18): an origin beyond 2^60 (a far ray that ray
// conditioning could not move near the scene) is outside Embree's domain and answered as a miss.
constexpr float kEmbreeLargest = 0x1p60f;
// Embree replaces a zero direction component's reciprocal by 1e18 (rcp_safe) and takes any other's as it is.
// A component below 2^-59 thus gives a reciprocal beyond Embree's own bound, whose products with coordinates
// overflow its slab and frustum tests: its 8- and 16-ray calls and its streams then skipped boxes the ray
// crosses and, under the COHERENT flag, aborted on an empty child (docs/robustness.md, finding 34).
constexpr float kEmbreeSmallestComponent = 0x1p-59f;
// Embree runs with denormals read as zero (below), so a denormal tnear or tfar is 0 to it: a hit may come
// back behind the caller's tnear, or for an empty interval. Such rays go through to_embree, whose interval
// test and t clamp do not rest on float comparisons. Told from the bits, since the tests below run in that
// mode too, where a denormal compares equal to 0.
constexpr std::uint32_t kMagnitudeBits = 0x7fffffffu, kSmallestNormalBits = 0x00800000u;
bool zero_or_normal(float x) {
    const std::uint32_t magnitude = std::bit_cast<std::uint32_t>(x) & kMagnitudeBits;
    return magnitude == 0 || magnitude >= kSmallestNormalBits;
}

// A direction component Embree takes as it is: 0 or at least kEmbreeSmallestComponent. Without a branch
// (both comparisons evaluated), so that fill_from_packet's loop still vectorizes.
bool usable_component(float component) {
    return static_cast<bool>(static_cast<int>(component == 0.0f) |
                             static_cast<int>(std::fabs(component) >= kEmbreeSmallestComponent));
}

bool usable_direction(const Vec3f& direction) {
    return usable_component(direction.x) && usable_component(direction.y) && usable_component(direction.z);
}

// The floats' order as integers, +0 and -0 alike (NaN excluded).
std::int32_t order_key(float x) {
    const auto bits = std::bit_cast<std::int32_t>(x);
    return bits >= 0 ? bits : -(bits & std::numeric_limits<std::int32_t>::max());
}

// t clamped to [tnear, tfar], in the floats' order as integers: this runs with denormals read as zero, where
// a denormal tnear compares equal to 0 and std::clamp would let a t of 0 below it through (to_embree's rays).
float in_interval(float t, float tnear, float tfar) {
    const std::int32_t key = order_key(t);
    return key < order_key(tnear) ? tnear : (key > order_key(tfar) ? tfar : t);
}

// A ray as Embree is given it: lancer's t = Embree's t * scale + t_offset, kept in the caller's
// [tnear, tfar], which the rounded shift back could leave by an ulp (fuzz/rays_fuzz.cpp). `scale` is a power
// of two, the scene's and the direction's scales together, in double, whose range holds both.
struct EmbreeRay {
    Ray ray;
    double scale = 1.0;
    float t_offset = 0.0f;
    float tnear = 0.0f, tfar = kInfinity;  // the caller's interval

    [[nodiscard]] float lancer_t(float embree_t) const {
        return in_interval(static_cast<float>(embree_t * scale) + t_offset, tnear, tfar);
    }
};

// The ray in Embree's domain and scale, or none: invalid rays (is_valid) and origins beyond kEmbreeLargest
// miss. A direction with a non-zero component below kEmbreeSmallestComponent is scaled into [1/2, 1) by a
// power of two and such components are set to zero: the line turns by less than 2^-58 rad. Embree also
// asserts tnear >= 0 (Debian's build keeps its assertions; found by fuzz/rays_fuzz.cpp, docs/robustness.md):
// a ray whose interval starts behind its origin starts where it enters the scene's box (grown by the
// geometric tolerance) instead, so that the origin Embree sees lies near the scene even when tnear is far
// behind (a far ray moved near the scene by Accel::intersect comes with tnear < 0).
std::optional<EmbreeRay> to_embree(const Ray& ray, const Box3f& scene_box, float scene_scale) {
    // is_valid's tnear <= tfar, in the floats' integer order: under denormals-are-zero, a denormal interval
    // that is empty (tnear > tfar) compares as [0, 0].
    if (!is_valid(ray) || order_key(ray.tnear) > order_key(ray.tfar)) return std::nullopt;
    EmbreeRay query{ray};
    query.tnear = ray.tnear, query.tfar = ray.tfar;
    if (ray.tnear < 0.0f) {
        float entry = 0.0f, exit = 0.0f;
        if (!intersect_box(SlabRay(ray), scene_box, ray.tnear, ray.tfar, entry, exit)) return std::nullopt;
        // Nothing lies in [tnear, entry): from an entry ahead of the origin, Embree's [0, tfar] is enough.
        const float start = std::min(entry, 0.0f);
        query.ray.origin = ray.origin + ray.direction * start;
        query.ray.tnear = 0.0f;
        query.ray.tfar = ray.tfar - start;
        query.t_offset = start;
    }
    query.ray.origin *= scene_scale;
    if (!is_finite(query.ray.origin) || max_component(abs(query.ray.origin)) > kEmbreeLargest)
        return std::nullopt;
    // A direction with a component Embree cannot take is scaled into [1/2, 1) by a power of two, where such
    // components are set to zero; any other is left as it is, which keeps Embree's products of small
    // features and directions out of its flushed denormals.
    float direction_scale = 1.0f;
    if (!usable_direction(ray.direction)) {
        int exponent = 0;
        static_cast<void>(std::frexp(max_component(abs(ray.direction)), &exponent));
        direction_scale = std::ldexp(1.0f, -exponent);
        auto scaled_component = [&](float component) {
            const float scaled = component * direction_scale;
            return std::fabs(scaled) < kEmbreeSmallestComponent ? 0.0f : scaled;
        };
        query.ray.direction = {scaled_component(ray.direction.x), scaled_component(ray.direction.y),
                               scaled_component(ray.direction.z)};
    }
    // Exact but where t' overflows: a tnear or tfar beyond every point of float coordinates, where infinity
    // answers the same.
    query.scale = double(direction_scale) / double(scene_scale);
    query.ray.tnear = query.ray.tnear * scene_scale / direction_scale;
    query.ray.tfar = query.ray.tfar * scene_scale / direction_scale;
    return query;
}

// Embree numbers primitives per geometry; lancer's global numbering puts the spheres after the triangles.
Hit to_hit(float t, unsigned int geometry, unsigned int primitive, float u, float v,
           unsigned int triangle_count) {
    // A t that overflows when scaled back (scene_scale) is no hit, as in lancer's own kernels: a hit is at a
    // finite distance (docs/numerical-contract.md).
    if (geometry == RTC_INVALID_GEOMETRY_ID || !std::isfinite(t)) return Hit{};
    const unsigned int global = geometry == kEmbreeSphereGeometry ? triangle_count + primitive : primitive;
    return {t, static_cast<std::int32_t>(global), u, v};
}

// One lane of a packet, written straight into Embree's SoA layout.
template <int N>
void fill_lane(const Ray& ray, RTCRayNt<N>& out, int lane) {
    out.org_x[lane] = ray.origin.x, out.org_y[lane] = ray.origin.y, out.org_z[lane] = ray.origin.z;
    out.dir_x[lane] = ray.direction.x, out.dir_y[lane] = ray.direction.y, out.dir_z[lane] = ray.direction.z;
    out.tnear[lane] = ray.tnear, out.tfar[lane] = ray.tfar;
    out.time[lane] = 0.0f, out.mask[lane] = ~0u, out.id[lane] = 0, out.flags[lane] = 0;
}

template <int N>
void fill_lane(const Ray& ray, RTCRayHitNt<N>& out, int lane) {
    fill_lane(ray, out.ray, lane);
    out.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
}

// Whether Embree takes the ray as it is: a valid ray with tnear and tfar 0 or normal, an origin within
// Embree's domain and usable direction components, in a scene that is not scaled. Every camera and secondary
// ray of an ordinary scene is such a ray, and skips to_embree's work. Its t needs only as_is_t.
bool taken_as_is(const Ray& ray) {
    return ray.tnear >= 0.0f && zero_or_normal(ray.tnear) && zero_or_normal(ray.tfar) && is_valid(ray) &&
           max_component(abs(ray.origin)) <= kEmbreeLargest && usable_direction(ray.direction);
}

// The t of a ray taken as it is, back in its interval, where a hit lies (docs/numerical-contract.md, "Hits"):
// Embree's fast test may pass tfar by a rounding error (its reciprocal of the determinant). With tnear and
// tfar 0 or normal, and Embree's t never denormal (flush-to-zero), float comparisons are exact even with
// denormals read as zero.
float as_is_t(float t, float tnear, float tfar) {
    return std::min(std::max(t, tnear), tfar);
}

#if defined(__AVX2__)
// zero_or_normal lane by lane: all ones where the magnitude's bits are 0 or above the largest denormal's.
__m256 zero_or_normal(__m256 x) {
    const __m256i magnitude =
        _mm256_and_si256(_mm256_castps_si256(x), _mm256_set1_epi32(static_cast<int>(kMagnitudeBits)));
    return _mm256_castsi256_ps(_mm256_or_si256(
        _mm256_cmpeq_epi32(magnitude, _mm256_setzero_si256()),
        _mm256_cmpgt_epi32(magnitude, _mm256_set1_epi32(static_cast<int>(kSmallestNormalBits - 1)))));
}

// Eight rays into lanes [first_lane, first_lane + 8) of a packet, as they are, transposed from lancer's
// layout (8 floats a ray: origin, direction, tnear, tfar) to Embree's SoA (simd::Avx2::load_fields8).
// Returns whether Embree takes all eight as they are (taken_as_is, the same tests in SIMD); when it does not,
// the caller writes the lanes one by one over these.
template <int N>
bool fill_eight_as_is(const Ray* rays, RTCRayNt<N>& out, int first_lane) {
    static_assert(sizeof(Ray) == 8 * sizeof(float) && offsetof(Ray, tfar) == 7 * sizeof(float));
    __m256 column[8];
    simd::Avx2::load_fields8(&rays[0].origin.x, column);
    // column: origin x, y, z, direction x, y, z, tnear, tfar across the eight rays.
    const __m256 sign = _mm256_set1_ps(-0.0f), zero = _mm256_setzero_ps();
    const __m256 largest = _mm256_set1_ps(kEmbreeLargest), infinity = _mm256_set1_ps(kInfinity);
    const __m256 smallest_component = _mm256_set1_ps(kEmbreeSmallestComponent);
    __m256 taken = _mm256_cmp_ps(column[6], zero, _CMP_GE_OQ);  // 0 <= tnear
    taken = _mm256_and_ps(taken, _mm256_and_ps(zero_or_normal(column[6]), zero_or_normal(column[7])));
    taken = _mm256_and_ps(taken, _mm256_cmp_ps(column[6], infinity, _CMP_LT_OQ));   // tnear finite
    taken = _mm256_and_ps(taken, _mm256_cmp_ps(column[6], column[7], _CMP_LE_OQ));  // tnear <= tfar
    __m256 nonzero = zero;
    for (int axis = 0; axis < 3; ++axis) {
        taken =
            _mm256_and_ps(taken, _mm256_cmp_ps(_mm256_andnot_ps(sign, column[axis]), largest, _CMP_LE_OQ));
        const __m256 component = _mm256_andnot_ps(sign, column[axis + 3]);  // |d|
        taken = _mm256_and_ps(taken, _mm256_cmp_ps(component, infinity, _CMP_LT_OQ));
        // usable_component: 0 or at least kEmbreeSmallestComponent
        taken = _mm256_and_ps(taken, _mm256_or_ps(_mm256_cmp_ps(component, zero, _CMP_EQ_OQ),
                                                  _mm256_cmp_ps(component, smallest_component, _CMP_GE_OQ)));
        nonzero = _mm256_or_ps(nonzero, _mm256_cmp_ps(column[axis + 3], zero, _CMP_NEQ_OQ));
    }
    taken = _mm256_and_ps(taken, nonzero);
    float* const fields[8] = {out.org_x, out.org_y, out.org_z, out.dir_x,
                              out.dir_y, out.dir_z, out.tnear, out.tfar};
    for (int i = 0; i < 8; ++i)
        _mm256_storeu_ps(fields[i] + first_lane, column[i]);
    _mm256_storeu_ps(out.time + first_lane, zero);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.mask + first_lane), _mm256_set1_epi32(-1));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.id + first_lane), _mm256_setzero_si256());
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.flags + first_lane), _mm256_setzero_si256());
    return _mm256_movemask_ps(taken) == 0xff;
}

template <int N>
bool fill_eight_as_is(const Ray* rays, RTCRayHitNt<N>& out, int first_lane) {
    const bool taken = fill_eight_as_is(rays, out.ray, first_lane);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.hit.geomID + first_lane),
                        _mm256_set1_epi32(static_cast<int>(RTC_INVALID_GEOMETRY_ID)));
    return taken;
}
#endif

// Lanes [first, first + N) of a caller's packet into an Embree packet, copied field by field (both are SoA),
// with valid[lane] set for the valid rays (is_valid); the others are masked off and keep the miss written
// here. Returns false when some valid ray is not taken as it is (taken_as_is), which the caller then traces
// through to_embree. Lane by lane on contiguous arrays, with an int accumulator, so that GCC vectorizes it.
template <int N>
bool fill_from_packet(const RayPacket& rays, int first, RTCRayHitNt<N>& out, int (&valid)[N]) {
    int all_taken = 1;
    for (int lane = 0; lane < N; ++lane) {
        const int index = first + lane;
        const float ox = rays.origin[0][index], oy = rays.origin[1][index], oz = rays.origin[2][index];
        const float dx = rays.direction[0][index], dy = rays.direction[1][index],
                    dz = rays.direction[2][index];
        const float tnear = rays.tnear[index], tfar = rays.tfar[index];
        // is_valid without branches (each comparison an int, combined bitwise), with `|x| < inf` for isfinite
        // and `tfar == tfar` for !isnan.
        auto bit = [](bool condition) { return static_cast<int>(condition); };
        const int is_valid_ray = bit(std::fabs(ox) < kInfinity) & bit(std::fabs(oy) < kInfinity) &
                                 bit(std::fabs(oz) < kInfinity) & bit(std::fabs(dx) < kInfinity) &
                                 bit(std::fabs(dy) < kInfinity) & bit(std::fabs(dz) < kInfinity) &
                                 (bit(dx != 0.0f) | bit(dy != 0.0f) | bit(dz != 0.0f)) &
                                 bit(std::fabs(tnear) < kInfinity) & bit(tfar == tfar) & bit(tnear <= tfar);
        const int as_is = bit(tnear >= 0.0f) & bit(zero_or_normal(tnear)) & bit(zero_or_normal(tfar)) &
                          bit(std::fabs(ox) <= kEmbreeLargest) & bit(std::fabs(oy) <= kEmbreeLargest) &
                          bit(std::fabs(oz) <= kEmbreeLargest) & bit(usable_component(dx)) &
                          bit(usable_component(dy)) & bit(usable_component(dz));
        all_taken &= (1 - is_valid_ray) | as_is;
        valid[lane] = -is_valid_ray;
        out.ray.org_x[lane] = ox, out.ray.org_y[lane] = oy, out.ray.org_z[lane] = oz;
        out.ray.dir_x[lane] = dx, out.ray.dir_y[lane] = dy, out.ray.dir_z[lane] = dz;
        out.ray.tnear[lane] = tnear, out.ray.tfar[lane] = tfar;
        out.ray.time[lane] = 0.0f, out.ray.mask[lane] = ~0u, out.ray.id[lane] = 0, out.ray.flags[lane] = 0;
        out.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
    }
    return all_taken != 0;
}

// Embree's call for each packet type, so that one loop (trace_packets) serves every width. A packet of one
// ray is laid out as Embree's single ray, and a masked one is not traced.
static_assert(sizeof(RTCRayHitNt<1>) == sizeof(RTCRayHit) &&
              offsetof(RTCRayHitNt<1>, hit) == offsetof(RTCRayHit, hit) &&
              sizeof(RTCRayNt<1>) == sizeof(RTCRay));
void query(const int* valid, RTCScene scene, RTCIntersectContext* context, RTCRayHitNt<1>& packet) {
    if (valid[0] != 0) rtcIntersect1(scene, context, reinterpret_cast<RTCRayHit*>(&packet));
}
void query(const int* valid, RTCScene scene, RTCIntersectContext* context, RTCRayHitNt<8>& packet) {
    rtcIntersect8(valid, scene, context, reinterpret_cast<RTCRayHit8*>(&packet));
}
void query(const int* valid, RTCScene scene, RTCIntersectContext* context, RTCRayHitNt<16>& packet) {
    rtcIntersect16(valid, scene, context, reinterpret_cast<RTCRayHit16*>(&packet));
}
void query(const int* valid, RTCScene scene, RTCIntersectContext* context, RTCRayNt<1>& packet) {
    if (valid[0] != 0) rtcOccluded1(scene, context, reinterpret_cast<RTCRay*>(&packet));
}
void query(const int* valid, RTCScene scene, RTCIntersectContext* context, RTCRayNt<8>& packet) {
    rtcOccluded8(valid, scene, context, reinterpret_cast<RTCRay8*>(&packet));
}
void query(const int* valid, RTCScene scene, RTCIntersectContext* context, RTCRayNt<16>& packet) {
    rtcOccluded16(valid, scene, context, reinterpret_cast<RTCRay16*>(&packet));
}

// Calls body(std::integral_constant<int, N>) with N the packet width of a packet call (1, 8 or 16).
template <class Body>
void with_packet_width(EmbreeCall call, Body&& body) {
    if (call == EmbreeCall::Packet16) {
        body(std::integral_constant<int, 16>{});
    } else if (call == EmbreeCall::Packet8) {
        body(std::integral_constant<int, 8>{});
    } else {
        body(std::integral_constant<int, 1>{});
    }
}

// The rays in packets of N consecutive rays (4x2 or 4x4 pixels of a coherent batch), or one by one for
// N = 1, with flush-to-zero set once for the batch. `answer(index, packet, lane, mapped)` stores ray
// `index`'s answer from its lane, where `mapped` is how its t maps back, or null for a ray taken as it is.
// Lanes of rays outside Embree's domain are masked off; they keep the miss fill_lane wrote (no geometry,
// tfar = +inf), so answer reads them as misses.
template <int N, class Packet, class Answer>
void trace_packets(RTCScene scene, RTCIntersectContext& context, const Box3f& scene_box, float scene_scale,
                   std::span<const Ray> rays, Answer&& answer) {
    const DenormalsFlushed flushed;
    const bool unscaled = scene_scale == 1.0f;
    for (std::size_t first = 0; first < rays.size(); first += N) {
        alignas(64) Packet packet;
        alignas(64) int valid[N];
        std::optional<EmbreeRay> mapped[N];
        const std::size_t lanes = std::min<std::size_t>(N, rays.size() - first);
        bool all_as_is = false;
#if defined(__AVX2__)
        // The common case, a full packet of rays taken as they are, eight lanes at a time.
        if (N % 8 == 0 && lanes == N && unscaled) {
            all_as_is = true;
            for (int lane = 0; lane < N; lane += 8)
                all_as_is &= fill_eight_as_is(&rays[first + static_cast<std::size_t>(lane)], packet, lane);
            if (all_as_is) std::fill_n(valid, N, -1);
        }
#endif
        for (std::size_t lane = 0; lane < N && !all_as_is; ++lane) {
            const int lane_index = static_cast<int>(lane);
            if (lane < lanes && unscaled && taken_as_is(rays[first + lane])) {
                fill_lane(rays[first + lane], packet, lane_index);
                valid[lane] = -1;
                continue;
            }
            if (lane < lanes) mapped[lane] = to_embree(rays[first + lane], scene_box, scene_scale);
            valid[lane] = mapped[lane] ? -1 : 0;
            fill_lane(mapped[lane] ? mapped[lane]->ray : Ray{}, packet, lane_index);
        }
        query(valid, scene, &context, packet);
        for (std::size_t lane = 0; lane < lanes; ++lane)
            answer(first + lane, packet, static_cast<int>(lane), mapped[lane] ? &*mapped[lane] : nullptr);
    }
}

// Rays per stream call of embree_stream on a batch. Embree 3.13's stream filter works on 64 rays at a time:
// it cuts a COHERENT stream into streams of 64, and sorts the rays of an incoherent occlusion stream into
// groups of up to 64 that share their direction octant (kernels/bvh/bvh_intersector_stream_filters.cpp); a
// chunk of four such groups lets the sorted groups fill while its records (80 bytes a ray) stay in the
// caches.
constexpr std::size_t kStreamChunk = 256;

// A record Embree skips: a stream's ray is inactive when its tnear exceeds its tfar (rtcIntersect1M's manual
// page). Its fields stay finite, so that no assertion of Embree's sees a malformed ray, and Embree leaves its
// answer as written: no geometry (fill_lane), tfar not -inf (not occluded).
constexpr Ray kInactiveRay{{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 1.0f, 0.0f};

// A stream of records laid out as Embree's single ray (RTCRayHitNt<1> as RTCRayHit, RTCRayNt<1> as RTCRay),
// which the stream calls take 16-byte aligned.
static_assert(sizeof(RTCRayHitNt<1>) % 16 == 0 && sizeof(RTCRayNt<1>) % 16 == 0);
void stream_query(RTCScene scene, RTCIntersectContext* context, RTCRayHitNt<1>* stream, unsigned int count) {
    rtcIntersect1M(scene, context, reinterpret_cast<RTCRayHit*>(stream), count, sizeof(RTCRayHit));
}
void stream_query(RTCScene scene, RTCIntersectContext* context, RTCRayNt<1>* stream, unsigned int count) {
    rtcOccluded1M(scene, context, reinterpret_cast<RTCRay*>(stream), count, sizeof(RTCRay));
}

// The rays in streams of kStreamChunk consecutive rays, one rtcIntersect1M or rtcOccluded1M call each, with
// flush-to-zero set once for the batch; `answer` as trace_packets', each record a packet of one lane. A ray
// outside Embree's domain is an inactive record, which answer reads as a miss.
template <class Record, class Answer>
void trace_stream(RTCScene scene, RTCIntersectContext& context, const Box3f& scene_box, float scene_scale,
                  std::span<const Ray> rays, Answer&& answer) {
    const DenormalsFlushed flushed;
    const bool unscaled = scene_scale == 1.0f;
    alignas(64) Record stream[kStreamChunk];
    std::optional<EmbreeRay> mapped[kStreamChunk];
    for (std::size_t first = 0; first < rays.size(); first += kStreamChunk) {
        const std::size_t count = std::min(kStreamChunk, rays.size() - first);
        for (std::size_t i = 0; i < count; ++i) {
            const Ray& ray = rays[first + i];
            if (unscaled && taken_as_is(ray)) {
                mapped[i].reset();
                fill_lane(ray, stream[i], 0);
                continue;
            }
            mapped[i] = to_embree(ray, scene_box, scene_scale);
            fill_lane(mapped[i] ? mapped[i]->ray : kInactiveRay, stream[i], 0);
        }
        stream_query(scene, &context, stream, static_cast<unsigned int>(count));
        for (std::size_t i = 0; i < count; ++i)
            answer(first + i, stream[i], 0, mapped[i] ? &*mapped[i] : nullptr);
    }
}

// A packet's hits into lanes [first, first + N) of `hits`: to_hit lane by lane, without branches, for rays
// taken as they are in a scene that is not scaled, where t is finite on a hit.
template <int N>
void store_hits(const RTCRayHitNt<N>& packet, const RayPacket& rays, int first, std::int32_t sphere_offset,
                HitPacket& hits) {
    for (int lane = 0; lane < N; ++lane) {
        const auto geometry = static_cast<std::int32_t>(packet.hit.geomID[lane]);
        const auto primitive = static_cast<std::int32_t>(packet.hit.primID[lane]);
        const int hit = geometry != static_cast<std::int32_t>(RTC_INVALID_GEOMETRY_ID);
        const int sphere = geometry == static_cast<std::int32_t>(kEmbreeSphereGeometry);
        hits.t[first + lane] =
            hit ? as_is_t(packet.ray.tfar[lane], rays.tnear[first + lane], rays.tfar[first + lane])
                : kInfinity;
        hits.prim[first + lane] = hit ? primitive + sphere * sphere_offset : -1;
        hits.u[first + lane] = hit ? packet.hit.u[lane] : 0.0f;
        hits.v[first + lane] = hit ? packet.hit.v[lane] : 0.0f;
    }
}

}  // namespace

void EmbreeAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                  TraversalCounters* counters) const {
    if (counters != nullptr) counters->rays += rays.size();  // Embree exposes no traversal counts
    intersect_with_flags(rays, hits, RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
}

void EmbreeAccel::intersect_coherent_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                           TraversalCounters* counters) const {
    if (counters != nullptr) counters->rays += rays.size();
    intersect_with_flags(rays, hits, RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
}

void EmbreeAccel::intersect_with_flags(std::span<const Ray> rays, std::span<Hit> hits,
                                       RTCIntersectContextFlags flags) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = flags;
    const auto answer = [&](std::size_t index, const auto& packet, int lane, const EmbreeRay* mapped) {
        const float t = packet.ray.tfar[lane];
        hits[index] = to_hit(mapped ? mapped->lancer_t(t) : as_is_t(t, rays[index].tnear, rays[index].tfar),
                             packet.hit.geomID[lane], packet.hit.primID[lane], packet.hit.u[lane],
                             packet.hit.v[lane], triangle_count_);
    };
    if (call_ == EmbreeCall::Stream) {
        trace_stream<RTCRayHitNt<1>>(scene_, context, scene_box_, scene_scale_, rays, answer);
        return;
    }
    with_packet_width(call_, [&](auto width) {
        constexpr int N = decltype(width)::value;
        trace_packets<N, RTCRayHitNt<N>>(scene_, context, scene_box_, scene_scale_, rays, answer);
    });
}

// Each run of N lanes of the packet through one packet call, the rays read in place, or the whole packet as
// one stream (embree_stream); when some valid ray is not taken as it is, or the scene is scaled, the packet
// takes the batch path, which maps rays one by one.
void EmbreeAccel::intersect_packet_rays(const RayPacket& rays, HitPacket& hits,
                                        TraversalCounters* counters) const {
    if (scene_scale_ != 1.0f) {
        Accel::intersect_packet_rays(rays, hits, counters);
        return;
    }
    // A partial packet is padded with invalid rays (zero direction), so that every lane read is a ray.
    const RayPacket* source = &rays;
    RayPacket padded;
    if (rays.size < RayPacket::kMaxSize) {
        padded = rays;
        for (int lane = rays.size; lane < RayPacket::kMaxSize; ++lane)
            padded.set(lane, Ray{{}, {}, 0.0f, 0.0f});
        source = &padded;
    }
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    bool traced = true;
    const auto sphere_offset = static_cast<std::int32_t>(triangle_count_);
    {
        const DenormalsFlushed flushed;
        if (call_ == EmbreeCall::Stream) {
            // The packet's rays as one stream, its invalid rays inactive records: the tests over all lanes
            // at once (fill_from_packet, vectorized), then the records ray by ray from the tested packet.
            alignas(64) RTCRayHitNt<RayPacket::kMaxSize> tested;
            alignas(64) int valid[RayPacket::kMaxSize];
            traced = fill_from_packet(*source, 0, tested, valid);
            alignas(64) RTCRayHitNt<1> stream[RayPacket::kMaxSize];
            for (int lane = 0; lane < rays.size && traced; ++lane) {
                const Ray ray{{tested.ray.org_x[lane], tested.ray.org_y[lane], tested.ray.org_z[lane]},
                              {tested.ray.dir_x[lane], tested.ray.dir_y[lane], tested.ray.dir_z[lane]},
                              tested.ray.tnear[lane],
                              tested.ray.tfar[lane]};
                fill_lane(valid[lane] != 0 ? ray : kInactiveRay, stream[lane], 0);
            }
            if (traced) {
                stream_query(scene_, &context, stream, static_cast<unsigned int>(rays.size));
                for (int lane = 0; lane < rays.size; ++lane)
                    store_hits(stream[lane], *source, lane, sphere_offset, hits);
            }
        } else {
            with_packet_width(call_, [&](auto width) {
                constexpr int N = decltype(width)::value;
                for (int first = 0; first < rays.size && traced; first += N) {
                    alignas(64) RTCRayHitNt<N> packet;
                    alignas(64) int valid[N];
                    traced = fill_from_packet(*source, first, packet, valid);
                    if (!traced) break;
                    query(valid, scene_, &context, packet);
                    store_hits(packet, *source, first, sphere_offset, hits);
                }
            });
        }
    }
    if (!traced) {
        Accel::intersect_packet_rays(rays, hits, counters);
        return;
    }
    if (counters != nullptr) counters->rays += static_cast<std::uint64_t>(rays.size);
}

// Embree marks an occluded ray with tfar = -inf. Occlusion rays are shadow rays, towards a light, and each
// call gets the flag under which it is fastest on VIEWS.md's shadow view (docs/results.md, "Which context
// flag suits which view"): COHERENT for the 8- and 16-ray packets, INCOHERENT (the default) for a stream,
// which Embree then sorts by direction itself.
void EmbreeAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                 TraversalCounters* counters) const {
    if (counters != nullptr) counters->rays += rays.size();
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    if (call_ == EmbreeCall::Packet8 || call_ == EmbreeCall::Packet16)
        context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    const auto answer = [&](std::size_t index, const auto& packet, int lane, const EmbreeRay*) {
        occluded[index] = packet.tfar[lane] == -kInfinity ? 1 : 0;
    };
    if (call_ == EmbreeCall::Stream) {
        trace_stream<RTCRayNt<1>>(scene_, context, scene_box_, scene_scale_, rays, answer);
        return;
    }
    with_packet_width(call_, [&](auto width) {
        constexpr int N = decltype(width)::value;
        trace_packets<N, RTCRayNt<N>>(scene_, context, scene_box_, scene_scale_, rays, answer);
    });
}

}  // namespace lancer
