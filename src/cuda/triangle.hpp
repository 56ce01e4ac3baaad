// The two triangle tests of core/intersect.hpp (Moller-Trumbore 1997; Woop, Benthin & Wald 2013) for the
// host and the device: the same operations in the same order, so that with unfused products (g++
// -ffp-contract=off, nvcc --fmad=false) and IEEE division (nvcc's default -prec-div=true) both return the
// CPU's t, u and v bit for bit (tests/cuda/port_test.cpp). Spheres are not ported: the GPU path
// traces triangle meshes (docs/cuda.md).
#pragma once

#include "cuda/host_device.hpp"
#include "lancer/scene.hpp"

namespace lancer::gpu {

struct TriangleHitRecord {
    float t, u, v;
};

struct MollerTrumboreTest {
    // MollerTrumbore's constants.
    static constexpr float kIllConditioned = 0x1p-20f;
    static constexpr float kGrazingScale = 0x1p-8f / 0x1p-20f;
    static constexpr float kRoundingSlack = 0x1p-17f;

    struct RayData {
        Vec3f origin, direction;
        float direction_scale;
        LANCER_HOST_DEVICE explicit RayData(const Ray& ray)
            : origin(ray.origin), direction(ray.direction), direction_scale(0.0f) {
            const Vec3f a = abs_of(ray.direction);
            direction_scale = max_of(a.x, max_of(a.y, a.z));
        }
    };

    LANCER_HOST_DEVICE static bool intersect(const RayData& ray, const Triangle& tri, float tnear, float tfar,
                                             TriangleHitRecord& out) {
        const Vec3f e1 = tri.v1 - tri.v0;
        const Vec3f e2 = tri.v2 - tri.v0;
        const Vec3f p = cross(ray.direction, e2);
        const float det = dot(p, e1);
        const Vec3f a1 = abs_of(e1), a2 = abs_of(e2);
        const float e1_scale = max_of(a1.x, max_of(a1.y, a1.z)), e2_scale = max_of(a2.x, max_of(a2.y, a2.z));
        // A det beyond the float range is a miss, as in core/intersect.hpp (docs/numerical-contract.md,
        // "Triangle tests").
        const float band = kIllConditioned * ray.direction_scale * e1_scale * e2_scale;
        if (!(abs_of(det) > band && abs_of(det) < kInfinity)) return false;
        const float inv_det = 1.0f / det;
        const Vec3f to_origin = ray.origin - tri.v0;
        // Widened float screens; a grazing ray, or one within the float error bound of an edge, is decided
        // by the double test (core/intersect.hpp; docs/numerical-contract.md, "Triangle tests").
        const bool grazing = abs_of(det) <= band * kGrazingScale;
        const Vec3f a0 = abs_of(to_origin);
        const float slack = kRoundingSlack * ray.direction_scale *
                            (max_of(a0.x, max_of(a0.y, a0.z)) + e1_scale + e2_scale) * abs_of(inv_det);
        const float slack_u = slack * e2_scale, slack_v = slack * e1_scale;
        const float u = dot(to_origin, p) * inv_det;
        if (!(u >= -slack_u && u <= 1.0f + slack_u)) return false;
        const Vec3f q = cross(to_origin, e1);
        const float v = dot(ray.direction, q) * inv_det;
        if (!(v >= -slack_v && u + v <= 1.0f + (slack_u + slack_v))) return false;
        const bool certain = u >= slack_u && v >= slack_v && u + v <= 1.0f - (slack_u + slack_v);
        if (grazing || !certain) return intersect_in_double(ray, tri, tnear, tfar, out);
        const float t = dot(e2, q) * inv_det;
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;
        out = {t, u, v};
        return true;
    }

    // MollerTrumbore::intersect_in_double.
    LANCER_HOST_DEVICE static bool intersect_in_double(const RayData& ray, const Triangle& tri, float tnear,
                                                       float tfar, TriangleHitRecord& out) {
        const double v0x = tri.v0.x, v0y = tri.v0.y, v0z = tri.v0.z;
        const double dx = ray.direction.x, dy = ray.direction.y, dz = ray.direction.z;
        const double e1x = double(tri.v1.x) - v0x, e1y = double(tri.v1.y) - v0y, e1z = double(tri.v1.z) - v0z;
        const double e2x = double(tri.v2.x) - v0x, e2y = double(tri.v2.y) - v0y, e2z = double(tri.v2.z) - v0z;
        const double px = dy * e2z - dz * e2y, py = dz * e2x - dx * e2z, pz = dx * e2y - dy * e2x;
        const double det = px * e1x + py * e1y + pz * e1z;
        if (det == 0.0) return false;
        const double inv_det = 1.0 / det;
        const double sx = double(ray.origin.x) - v0x, sy = double(ray.origin.y) - v0y,
                     sz = double(ray.origin.z) - v0z;
        const double u = (sx * px + sy * py + sz * pz) * inv_det;
        if (!(u >= 0.0 && u <= 1.0)) return false;
        const double qx = sy * e1z - sz * e1y, qy = sz * e1x - sx * e1z, qz = sx * e1y - sy * e1x;
        const double v = (dx * qx + dy * qy + dz * qz) * inv_det;
        if (!(v >= 0.0 && u + v <= 1.0)) return false;
        const float t = static_cast<float>((e2x * qx + e2y * qy + e2z * qz) * inv_det);
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;
        out = {t, static_cast<float>(u), static_cast<float>(v)};
        return true;
    }
};

struct WatertightTest {
    struct RayData {
        Vec3f origin;
        int kx, ky, kz;
        float shear_x, shear_y, shear_z;

        LANCER_HOST_DEVICE explicit RayData(const Ray& ray) : origin(ray.origin) {
            const Vec3f a = abs_of(ray.direction);
            // max_axis of lancer/vec.hpp, ties to the lower axis.
            kz = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
            kx = kz == 2 ? 0 : kz + 1;
            ky = kx == 2 ? 0 : kx + 1;
            if (ray.direction[kz] < 0.0f) {
                const int swapped = kx;
                kx = ky, ky = swapped;
            }
            shear_x = ray.direction[kx] / ray.direction[kz];
            shear_y = ray.direction[ky] / ray.direction[kz];
            shear_z = 1.0f / ray.direction[kz];
        }
    };

    // Watertight's constant: below this |T| the numerator is computed in double.
    static constexpr float kSmallNumerator = 0x1p-100f;

    LANCER_HOST_DEVICE static bool intersect(const RayData& ray, const Triangle& tri, float tnear, float tfar,
                                             TriangleHitRecord& out) {
        const Vec3f a = tri.v0 - ray.origin;
        const Vec3f b = tri.v1 - ray.origin;
        const Vec3f c = tri.v2 - ray.origin;
        const Sheared v = {
            a[ray.kx] - ray.shear_x * a[ray.kz], a[ray.ky] - ray.shear_y * a[ray.kz], a[ray.kz],
            b[ray.kx] - ray.shear_x * b[ray.kz], b[ray.ky] - ray.shear_y * b[ray.kz], b[ray.kz],
            c[ray.kx] - ray.shear_x * c[ray.kz], c[ray.ky] - ray.shear_y * c[ray.kz], c[ray.kz]};
        const float w0 = v.bx * v.cy - v.by * v.cx;
        const float w1 = v.cx * v.ay - v.cy * v.ax;
        const float w2 = v.ax * v.by - v.ay * v.bx;
        // Both signs, strictly: a miss before the double fallback (core/intersect.hpp).
        if ((w0 < 0.0f || w1 < 0.0f || w2 < 0.0f) && (w0 > 0.0f || w1 > 0.0f || w2 > 0.0f)) return false;
        constexpr float kFloatMin = 0x1p-126f;
        if (abs_of(w0) < kFloatMin || abs_of(w1) < kFloatMin || abs_of(w2) < kFloatMin)
            return intersect_in_double(ray, v, tnear, tfar, out);
        const float det = w0 + w1 + w2;
        const float az = ray.shear_z * v.az, bz = ray.shear_z * v.bz, cz = ray.shear_z * v.cz;
        const float numerator = w0 * az + w1 * bz + w2 * cz;
        if (abs_of(numerator) < kSmallNumerator) return intersect_in_double(ray, v, tnear, tfar, out);
        const float inv_det = 1.0f / det;
        const float t = numerator * inv_det;
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;
        out = {t, w1 * inv_det, w2 * inv_det};
        return true;
    }

  private:
    struct Sheared {
        float ax, ay, az, bx, by, bz, cx, cy, cz;
    };

    LANCER_HOST_DEVICE static bool intersect_in_double(const RayData& ray, const Sheared& v, float tnear,
                                                       float tfar, TriangleHitRecord& out) {
        const double w0 = double(v.bx) * v.cy - double(v.by) * v.cx;
        const double w1 = double(v.cx) * v.ay - double(v.cy) * v.ax;
        const double w2 = double(v.ax) * v.by - double(v.ay) * v.bx;
        if ((w0 < 0.0 || w1 < 0.0 || w2 < 0.0) && (w0 > 0.0 || w1 > 0.0 || w2 > 0.0)) return false;
        const double det = w0 + w1 + w2;
        if (det == 0.0) return false;
        const double shear_z = ray.shear_z;
        const auto t =
            static_cast<float>((w0 * (shear_z * v.az) + w1 * (shear_z * v.bz) + w2 * (shear_z * v.cz)) / det);
        if (!(t >= tnear && t <= tfar && t < kInfinity)) return false;
        out = {t, static_cast<float>(w1 / det), static_cast<float>(w2 / det)};
        return true;
    }
};

// A leaf's `count` triangle records from `records` (TriangleRef or PluckerPrimitive: a triangle and its
// global index), each tested within [tnear, the closest hit so far]; the closest wins, ties to the smaller
// index (closer() of lancer/ray.hpp).
template <class TriangleTestT, class Record>
LANCER_HOST_DEVICE void intersect_leaf(const Record* records, std::uint32_t count,
                                       const typename TriangleTestT::RayData& triangle_ray, const Ray& ray,
                                       Hit& best) {
    for (std::uint32_t r = 0; r < count; ++r) {
        const Record record = read_only_record(records + r);
        const float tfar = best.prim >= 0 ? best.t : ray.tfar;
        TriangleHitRecord candidate;
        const auto prim = static_cast<std::int32_t>(record.prim);
        if (TriangleTestT::intersect(triangle_ray, record.triangle, ray.tnear, tfar, candidate) &&
            is_closer(candidate.t, prim, best))
            best = {candidate.t, prim, candidate.u, candidate.v};
    }
}

}  // namespace lancer::gpu
