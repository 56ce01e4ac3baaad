// libFuzzer harness: reading a .plo Plücker octree file (src/accel/plucker/serialise.cpp). The contract:
// a damaged file is a PluckerFileError; a file that reads is a structure that agrees with brute force on
// its own geometry. The harness rewrites the header's checksum to match the bytes, so that mutations reach
// the checks behind it (the checksum itself is tested in tests/accel/plucker/plucker_file_test.cpp).
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "accel/plucker/plucker.hpp"
#include "accel/plucker/serialise.hpp"
#include "accel_check.hpp"
#include "fuzz_support.hpp"

namespace lancer::fuzz {
namespace {

// FNV-1a 64 of every byte after the header, as write_plucker_file stores it.
std::uint64_t payload_checksum(std::string_view payload) {
    std::uint64_t hash = 0xcbf29ce484222325ull;
    for (const char c : payload) {
        hash ^= static_cast<std::uint8_t>(c);
        hash *= 0x100000001b3ull;
    }
    return hash;
}

// Rays from outside the geometry's box through each primitive's middle, and back out again.
std::vector<Ray> rays_through(const plucker::PluckerFile& file) {
    const Geometry geometry{file.triangles, file.spheres};
    const Box3f bounds = geometry.bounds();
    const Vec3f outside = bounds.hi + (bounds.hi - bounds.lo) + Vec3f(1.0f);
    std::vector<Vec3f> targets;
    for (const Triangle& triangle : file.triangles)
        targets.push_back((triangle.v0 + triangle.v1 + triangle.v2) / 3.0f);
    for (const Sphere& sphere : file.spheres)
        targets.push_back(sphere.center);
    std::vector<Ray> rays;
    for (const Vec3f& target : targets) {
        rays.push_back({outside, target - outside});
        rays.push_back({target, outside - target});
    }
    return rays;
}

}  // namespace
}  // namespace lancer::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace lancer;
    using namespace lancer::plucker;
    std::string bytes(fuzz::as_text(data, size));
    if (bytes.size() >= sizeof(PluckerFileHeader)) {
        const std::uint64_t checksum =
            fuzz::payload_checksum(std::string_view(bytes).substr(sizeof(PluckerFileHeader)));
        std::memcpy(bytes.data() + offsetof(PluckerFileHeader, checksum), &checksum, sizeof checksum);
    }
    const std::filesystem::path path = fuzz::write_scratch_file("input.plo", bytes);
    PluckerFile file;
    try {
        file = read_plucker_file(path);
    } catch (const PluckerFileError&) {
        return 0;  // the contract for a damaged file
    } catch (const std::exception& error) {
        fuzz::finding(std::string("read_plucker_file threw something other than PluckerFileError: ") +
                      error.what());
    }
    const Geometry geometry{file.triangles, file.spheres};
    const std::vector<Ray> rays = fuzz::rays_through(file);
    const std::vector<Hit> oracle = fuzz::oracle_hits(geometry, file.triangle_test, rays);
    PluckerAccel loaded;
    loaded.adopt(geometry, build_options(file.triangle_test), std::move(file.layout));
    fuzz::check_agrees_with_oracle(loaded, rays, oracle, geometry);
    return 0;
}
