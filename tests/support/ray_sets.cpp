#include "ray_sets.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdio>
#include <limits>

#include "lancer/camera.hpp"

namespace lancer::testing {
namespace {

Vec3f random_point(const Box3f& box, std::mt19937& rng) {
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const Vec3f e = box.extent();
    // One draw per statement, z first (the order GCC gave a constructor's arguments, which is unspecified):
    // the same sets under every compiler.
    Vec3f p;
    p.z = unit(rng) * e.z;
    p.y = unit(rng) * e.y;
    p.x = unit(rng) * e.x;
    return box.lo + p;
}

Vec3f random_direction(std::mt19937& rng) {
    std::normal_distribution<float> gaussian;
    Vec3f d;
    do {
        d = {gaussian(rng), gaussian(rng), gaussian(rng)};
    } while (dot(d, d) < 1e-6f);
    return normalize(d);
}

Box3f enlarged(const Box3f& box, float factor) {
    const Vec3f margin = box.extent() * factor + Vec3f(1e-3f);
    return {box.lo - margin, box.hi + margin};
}

}  // namespace

RaySet random_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed) {
    std::mt19937 rng(seed);
    const Box3f around = enlarged(bounds, 0.5f);
    RaySet set{"random", {}};
    set.rays.reserve(count);
    for (std::size_t i = 0; i < count; ++i) {
        // Half start inside the box, half around it aiming at a point inside.
        const Vec3f origin = random_point(i % 2 ? bounds : around, rng);
        const Vec3f direction = i % 2 ? random_direction(rng) : random_point(bounds, rng) - origin;
        set.rays.push_back({origin, direction, 0.0f, kInfinity});
    }
    return set;
}

RaySet vertex_and_edge_rays(std::span<const Triangle> triangles, std::size_t count, std::uint32_t seed) {
    std::mt19937 rng(seed);
    RaySet set{"vertices and edges", {}};
    if (triangles.empty()) return set;
    Box3f bounds;
    for (const Triangle& tri : triangles)
        bounds.extend(tri.bounds());
    const Box3f around = enlarged(bounds, 0.5f);
    std::uniform_int_distribution<std::size_t> pick(0, triangles.size() - 1);
    std::uniform_real_distribution<float> fraction(0.0f, 1.0f);
    for (std::size_t i = 0; i < count; ++i) {
        const Triangle& tri = triangles[pick(rng)];
        const Vec3f corners[3] = {tri.v0, tri.v1, tri.v2};
        const int corner = static_cast<int>(i % 3);
        Vec3f target = corners[corner];
        if (i % 2) {  // a point along the edge from this corner to the next
            const float f = fraction(rng);
            target = (1.0f - f) * corners[corner] + f * corners[(corner + 1) % 3];
        }
        const Vec3f origin = random_point(i % 4 < 2 ? around : bounds, rng);
        set.rays.push_back({origin, target - origin, 0.0f, kInfinity});
    }
    return set;
}

RaySet axis_parallel_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed) {
    std::mt19937 rng(seed);
    const Box3f around = enlarged(bounds, 0.1f);
    RaySet set{"axis-parallel and zero components", {}};
    for (std::size_t i = 0; i < count; ++i) {
        Vec3f origin = random_point(around, rng);
        Vec3f direction = random_direction(rng);
        const int axis = static_cast<int>(i % 3);
        if (i % 2) {  // exactly along an axis
            direction = Vec3f(0.0f);
            direction[axis] = (i / 6) % 2 ? 1.0f : -1.0f;
        } else {  // one zero component
            direction[axis] = 0.0f;
        }
        if (i % 5 == 0) origin[(axis + 1) % 3] = bounds.lo[(axis + 1) % 3];  // start on a box face plane
        set.rays.push_back({origin, direction, 0.0f, kInfinity});
    }
    return set;
}

RaySet clipped_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed) {
    std::mt19937 rng(seed);
    RaySet set{"tnear > 0 and finite tfar", {}};
    const float diagonal = length(bounds.extent());
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const Box3f around = enlarged(bounds, 0.5f);
    for (std::size_t i = 0; i < count; ++i) {
        const Vec3f origin = random_point(around, rng);
        const Vec3f direction = normalize(random_point(bounds, rng) - origin);
        const float tnear = unit(rng) * diagonal;
        const float tfar = tnear + unit(rng) * diagonal;
        set.rays.push_back({origin, direction, tnear, tfar});
    }
    return set;
}

RaySet canonical_view_rays(const Box3f& bounds, int size) {
    const PinholeCamera camera(canonical_view(bounds, size, size));
    RaySet set{"canonical view", {}};
    set.rays.reserve(static_cast<std::size_t>(size) * static_cast<std::size_t>(size));
    for (int j = 0; j < size; ++j) {
        for (int i = 0; i < size; ++i) {
            set.rays.push_back(camera.generate(static_cast<float>(i) + 0.5f, static_cast<float>(j) + 0.5f));
        }
    }
    return set;
}

void keep_every(RaySet& set, std::size_t stride) {
    if (stride <= 1) return;
    const std::size_t total = set.rays.size();
    std::size_t kept = 0;
    for (std::size_t i = 0; i < total; i += stride)
        set.rays[kept++] = set.rays[i];
    set.rays.resize(kept);
    std::printf("%s: sanitized build, tracing 1/%zu of the rays (%zu of %zu)\n", set.name.c_str(), stride,
                kept, total);
}

std::vector<Hit> trace_in_parallel(const Accel& accel, std::span<const Ray> rays) {
    std::vector<Hit> hits(rays.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), 1024), [&](const auto& range) {
        accel.intersect(rays.subspan(range.begin(), range.size()),
                        std::span(hits).subspan(range.begin(), range.size()));
    });
    return hits;
}

const std::vector<Hit>& BruteForceCache::hits(std::size_t scene_index, std::size_t set_index,
                                              TriangleTest test, const Geometry& geometry,
                                              std::span<const Ray> rays) {
    auto [it, inserted] = hits_.try_emplace({scene_index, set_index, test});
    if (inserted) {
        const std::unique_ptr<Accel> brute = make_accel("brute");
        brute->build(geometry, build_options(test));
        it->second = trace_in_parallel(*brute, rays);
    }
    return it->second;
}

std::vector<Hit> intersect_in_packets(const Accel& accel, std::span<const Ray> rays) {
    std::vector<Hit> hits(rays.size());
    RayPacket packet;
    HitPacket packet_hits;
    std::size_t first = 0;
    for (int count = 0; first < rays.size(); ++count) {
        const std::size_t size = std::min<std::size_t>(
            rays.size() - first, count % 3 == 2 ? 1 + (static_cast<std::size_t>(count) * 37) % 63 : 64);
        packet.size = static_cast<int>(size);
        for (int lane = 0; lane < packet.size; ++lane)
            packet.set(lane, rays[first + static_cast<std::size_t>(lane)]);
        accel.intersect_packet(packet, packet_hits);
        for (int lane = 0; lane < packet.size; ++lane)
            hits[first + static_cast<std::size_t>(lane)] = packet_hits.hit(lane);
        first += size;
    }
    return hits;
}

RaySet hostile_rays(const Box3f& bounds) {
    constexpr float nan = std::numeric_limits<float>::quiet_NaN();
    constexpr float denormal = std::numeric_limits<float>::denorm_min();
    const Vec3f c = bounds.empty() ? Vec3f(0.0f) : bounds.center();
    const Vec3f outside =
        bounds.empty() ? Vec3f(0, 0, 10) : c + Vec3f(0, 0, 2.0f * length(bounds.extent()) + 1.0f);
    return {"hostile",
            {{outside, {0, 0, -1}, 0.0f, kInfinity},
             {{nan, c.y, c.z}, {0, 0, -1}, 0.0f, kInfinity},
             {outside, {nan, 0, -1}, 0.0f, kInfinity},
             {outside, {0, 0, -kInfinity}, 0.0f, kInfinity},
             {{kInfinity, 0, 0}, {-1, 0, 0}, 0.0f, kInfinity},
             {outside, {0, 0, 0}, 0.0f, kInfinity},
             {outside, {0, 0, -1}, 5.0f, 1.0f},
             {outside, {0, 0, -1}, nan, kInfinity},
             {outside, {0, 0, -1}, -kInfinity, kInfinity},
             {outside, {0, 0, -1}, 0.0f, nan},
             {outside, {denormal, denormal, -1}, 0.0f, kInfinity},
             {c, {denormal, 0, 0}, 0.0f, kInfinity},
             {c, {0, -denormal, 0}, 0.0f, kInfinity},
             {outside, {0, 0, -1e-30f}, 0.0f, kInfinity},
             {c, {1e30f, 1e30f, 1e30f}, 0.0f, kInfinity}}};
}

}  // namespace lancer::testing
