// Adversarial ray sets every structure is checked on against the brute-force oracle (STYLE.md, habit 5).
#pragma once

#include <map>
#include <random>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer::testing {

struct RaySet {
    std::string name;
    std::vector<Ray> rays;
};

// Random rays with origins inside and outside the (enlarged) box, random directions.
RaySet random_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed);
// Rays aimed exactly at triangle vertices and at points along edges, from random origins.
RaySet vertex_and_edge_rays(std::span<const Triangle> triangles, std::size_t count, std::uint32_t seed);
// Axis-parallel rays and rays with one or two zero direction components, some starting on box faces.
RaySet axis_parallel_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed);
// Rays with tnear > 0 and finite tfar cutting the interval around the surface.
RaySet clipped_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed);
// The primary rays of shared/bench/VIEWS.md's canonical view, size x size, row by row.
RaySet canonical_view_rays(const Box3f& bounds, int size = 1024);
// Under AddressSanitizer + UBSan (LANCER_SANITIZED, docs/robustness.md) the Stanford tests trace every
// kSanitizedStride-th ray of their sets, and the oracle, determinism, update, Plücker (leaf order and
// variants) and Embree tests generate kSanitizedShare times fewer rays per generated set (the hostile set
// stays whole), and the oracle test holds that many times fewer coincident triangles, so that the
// sanitized suite stays within CI's time; 1 otherwise.
#ifdef LANCER_SANITIZED
inline constexpr std::size_t kSanitizedStride = 16;
inline constexpr std::size_t kSanitizedShare = 4;
#else
inline constexpr std::size_t kSanitizedStride = 1;
inline constexpr std::size_t kSanitizedShare = 1;
#endif
// Keeps every stride-th ray of the set and prints how many it kept when it drops any.
void keep_every(RaySet& set, std::size_t stride);
// Closest hits of all rays, in parallel over oneTBB (large ray sets of the Stanford tests).
std::vector<Hit> trace_in_parallel(const Accel& accel, std::span<const Ray> rays);
// Closest hits of all rays through Accel::intersect_packet: the batch cut into packets of 64 rays, every
// third packet cut short (to 1 to 63 rays), so that partial packets are traced too.
std::vector<Hit> intersect_in_packets(const Accel& accel, std::span<const Ray> rays);
// Brute force's closest hits, computed the first time a (scene, ray set, triangle test) key is asked for and
// kept: the answers a parameterized test checks each of its structures or variants against. Such a test runs
// all its parameters in one process (ONE_PROCESS in tests/CMakeLists.txt), so that brute force runs once per
// key instead of once per parameter. The keys are a test's own indices, so each test keeps its own cache.
class BruteForceCache {
  public:
    const std::vector<Hit>& hits(std::size_t scene_index, std::size_t set_index, TriangleTest test,
                                 const Geometry& geometry, std::span<const Ray> rays);

  private:
    std::map<std::tuple<std::size_t, std::size_t, TriangleTest>, std::vector<Hit>> hits_;
};
// NaN, infinite, zero-direction, tnear > tfar, denormal directions: all must miss, except denormal ones
// which are valid and must agree with the oracle.
RaySet hostile_rays(const Box3f& bounds);

}  // namespace lancer::testing
