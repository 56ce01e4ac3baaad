// What the two-level scene's walk reads of objects and instances (InstancedScene, lancer/instances.hpp), and
// the one-ray tests a visit starts with: the world ray's validity and the object box cull. The walk is in
// top_level_walk.hpp; docs/accel/instances.md has the design note.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#if defined(__SSE4_1__) || defined(__AVX2__)
#include <immintrin.h>
#endif
#include <memory>
#include <vector>

#include "accel/bvh/bvh_wide.hpp"
#include "accel/instance/affine.hpp"
#include "core/intersect.hpp"
#include "core/ray_conditioning.hpp"
#include "lancer/accel.hpp"
#include "lancer/vec3d.hpp"

namespace lancer::top_level {

struct ObjectRecord {
    std::shared_ptr<const Accel> structure;
    // What the walk traces: the structure, or the single-ray structure a packet structure holds.
    const Accel* traced = nullptr;
    SingleRayWalk walk;  // traced's one-ray walk, where it has one
    // The triangles the scene flattened, when it built the object itself.
    std::shared_ptr<const std::vector<Triangle>> triangles;
    std::size_t primitives = 0;
    // Points whose convex hull holds the object's primitives grown by its geometric tolerance: the corners
    // of a 26-sided polytope around them (accel/instance/bounding_polytope.hpp), or of its grown box. An
    // instance's world box is the box of these points mapped.
    std::vector<Vec3d> hull_points;
};

// An object's box as the cull before an instance visit (crosses) reads it: the three axes in SSE lanes, the
// fourth 0.
struct alignas(16) ObjectBox {
    float lo[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    float hi[4] = {0.0f, 0.0f, 0.0f, 0.0f};

    ObjectBox() = default;
    explicit ObjectBox(const Box3f& box)
        : lo{box.lo.x, box.lo.y, box.lo.z, 0.0f}, hi{box.hi.x, box.hi.y, box.hi.z, 0.0f} {}
    [[nodiscard]] Box3f box() const { return {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}}; }
};

// Whether `ray` crosses `box` within [tnear, tfar]: intersect_box's slab test (core/intersect.hpp), its
// products, NaN rule (a NaN plane leaves the slab unbounded) and exit widening, on the three axes at once;
// the same answer, since the largest entry and the smallest exit do not depend on the order in which they
// are taken (InstancedScene.ObjectBoxCullAnswersAsTheSlabTest).
[[nodiscard]] inline bool crosses(const Ray& ray, const ObjectBox& box) {
#if defined(__SSE4_1__)
    const __m128 origin = _mm_loadu_ps(&ray.origin.x);        // x, y, z and direction.x
    const __m128 direction = _mm_loadu_ps(&ray.direction.x);  // x, y, z and tnear
    const __m128 inverse = _mm_div_ps(_mm_set1_ps(1.0f), direction);
    const __m128 to_lo = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(box.lo), origin), inverse);
    const __m128 to_hi = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(box.hi), origin), inverse);
    // The fourth lane, and an axis with a NaN plane, unbounded.
    const __m128 unbounded =
        _mm_or_ps(_mm_cmpunord_ps(to_lo, to_hi), _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, -1)));
    const __m128 exit = _mm_max_ps(to_lo, to_hi);
    const __m128 widened =
        _mm_mul_ps(exit, _mm_blendv_ps(_mm_set1_ps(kSlabExitShrink), _mm_set1_ps(kSlabExitGrow),
                                       _mm_cmpgt_ps(exit, _mm_setzero_ps())));
    __m128 t0 = _mm_blendv_ps(_mm_min_ps(to_lo, to_hi), _mm_set1_ps(-kInfinity), unbounded);
    __m128 t1 = _mm_blendv_ps(widened, _mm_set1_ps(kInfinity), unbounded);
    t0 = _mm_max_ps(t0, _mm_movehl_ps(t0, t0));
    t1 = _mm_min_ps(t1, _mm_movehl_ps(t1, t1));
    t0 = _mm_max_ss(_mm_max_ss(t0, _mm_shuffle_ps(t0, t0, 1)), _mm_set_ss(ray.tnear));
    t1 = _mm_min_ss(_mm_min_ss(t1, _mm_shuffle_ps(t1, t1, 1)), _mm_set_ss(ray.tfar));
    return _mm_comile_ss(t0, t1) != 0;
#else
    float t_entry = 0.0f, t_exit = 0.0f;
    return intersect_box(SlabRay(ray), box.box(), ray.tnear, ray.tfar, t_entry, t_exit);
#endif
}

// is_valid (lancer/ray.hpp) on the ray's 8 floats at once: origin, direction and tnear finite, a nonzero
// direction component, tfar not NaN and tnear <= tfar. The same answer (checked by
// InstancedScene.RayValidityAnswersAsIsValid) in a few vector instructions instead of is_valid's scalar tests
// of each component (docs/accel/instances.md, "The visit's overhead, cut").
[[nodiscard]] inline bool is_valid_ray(const Ray& ray) {
#if defined(__AVX2__)
    static_assert(sizeof(Ray) == 8 * sizeof(float));
    const __m256 lanes = _mm256_loadu_ps(&ray.origin.x);  // origin, direction, tnear, tfar
    const __m256 magnitude = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), lanes);
    const int finite = _mm256_movemask_ps(
        _mm256_cmp_ps(magnitude, _mm256_set1_ps(std::numeric_limits<float>::max()), _CMP_LE_OQ));
    const int nonzero = _mm256_movemask_ps(_mm256_cmp_ps(lanes, _mm256_setzero_ps(), _CMP_NEQ_UQ));
    return (finite & 0x7f) == 0x7f && (nonzero & 0x38) != 0 && ray.tfar == ray.tfar && ray.tnear <= ray.tfar;
#else
    return is_valid(ray);
#endif
}

// What the walk reads of an instance: 192 bytes.
struct InstanceRecord {
    InverseAffine to_object;
    const Accel* traced = nullptr;
    std::uint32_t object = 0;
    // Ray conditioning's far-origin frame of the object's box (FarOriginFrame): its centre, and the distance
    // beyond which an origin is far.
    Vec3f object_centre;
    float far_limit = kInfinity;
    SingleRayWalk walk;  // the object's (ObjectRecord::walk)
    // The object's box grown by its geometric tolerance: the box the top level maps to the world.
    ObjectBox object_box;
};
static_assert(sizeof(InstanceRecord) == 192);

// Whether ray conditioning would leave an object ray as it is (may_need_conditioning against the object's
// box): a direction in the ordinary range and an origin that is not far.
[[nodiscard]] inline bool is_ordinary(const Ray& ray, const InstanceRecord& record) {
    const float largest = max_component(abs(ray.direction));
    return largest >= kDirectionLowest && largest <= kDirectionHighest &&
           max_component(abs(ray.origin - record.object_centre)) <= record.far_limit;
}

// A packet of rays that walk the top level together: at most 64, a set of them by bit.
inline constexpr std::size_t kPacketRays = 64;
using RayMask = std::uint64_t;

// The top level's nodes: the wide BVH's (accel/bvh/bvh_wide.hpp), 8 children tested at once.
constexpr int kTopWidth = 8;
using TopNode = WideBvhNode<kTopWidth>;

}  // namespace lancer::top_level
