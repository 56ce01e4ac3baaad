#include "accel_check.hpp"

#include <cmath>
#include <cstdint>
#include <string>

#include "fuzz_support.hpp"
#include "lancer/agreement.hpp"

namespace lancer::fuzz {

namespace {

// A clean answer: invalid rays miss (is_valid), a miss is (t = +inf, prim = -1), a hit has a primitive of
// the geometry and a finite t in [tnear, tfar], and occlusion is 0 or 1.
void check_clean(const Accel& accel, std::span<const Ray> rays, std::span<const Hit> hits,
                 std::span<const std::uint8_t> occluded, const Geometry& geometry) {
    const std::string who(accel.name());
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit& hit = hits[i];
        if (!is_valid(rays[i]) && (hit.hit() || occluded[i] != 0))
            finding(who + ": an invalid ray found something (ray " + std::to_string(i) + ")");
        if (occluded[i] > 1) finding(who + ": occlusion is neither 0 nor 1");
        if (!hit.hit()) {
            if (hit.prim != -1 || hit.t != kInfinity) finding(who + ": a miss is not (t = +inf, prim = -1)");
            continue;
        }
        if (static_cast<std::size_t>(hit.prim) >= geometry.size())
            finding(who + ": a hit names primitive " + std::to_string(hit.prim) + " of " +
                    std::to_string(geometry.size()));
        if (!std::isfinite(hit.t) || hit.t < rays[i].tnear || hit.t > rays[i].tfar)
            finding(who + ": a hit's t lies outside [tnear, tfar] (ray " + std::to_string(i) + ")");
    }
}

std::vector<std::uint8_t> occlusion_of(const Accel& accel, std::span<const Ray> rays) {
    std::vector<std::uint8_t> occluded(rays.size(), 2);  // 2: a slot the structure did not write
    accel.occluded(rays, occluded);
    return occluded;
}

}  // namespace

std::vector<Hit> oracle_hits(const Geometry& geometry, TriangleTest test, std::span<const Ray> rays) {
    const std::unique_ptr<Accel> brute = make_accel("brute");
    brute->build(geometry, build_options(test));
    return oracle_hits(*brute, rays, geometry);
}

std::vector<Hit> oracle_hits(const Accel& brute, std::span<const Ray> rays, const Geometry& geometry) {
    std::vector<Hit> hits(rays.size());
    brute.intersect(rays, hits);
    check_clean(brute, rays, hits, occlusion_of(brute, rays), geometry);
    return hits;
}

void check_agrees_with_oracle(const Accel& accel, std::span<const Ray> rays, std::span<const Hit> oracle,
                              const Geometry& geometry) {
    std::vector<Hit> hits(rays.size());
    accel.intersect(rays, hits);
    const std::vector<std::uint8_t> occluded = occlusion_of(accel, rays);
    check_clean(accel, rays, hits, occluded, geometry);
    const Agreement closest = compare_hits(rays, oracle, hits);
    if (closest.mismatches > 0) finding(std::string(accel.name()) + " vs brute: " + closest.summary());
    const Agreement any = compare_occlusion(rays, oracle, occluded);
    if (any.mismatches > 0) finding(std::string(accel.name()) + " vs brute: " + any.summary());
}

void check_clean_answers(const Accel& accel, std::span<const Ray> rays, const Geometry& geometry) {
    std::vector<Hit> hits(rays.size());
    accel.intersect(rays, hits);
    check_clean(accel, rays, hits, occlusion_of(accel, rays), geometry);
}

}  // namespace lancer::fuzz
