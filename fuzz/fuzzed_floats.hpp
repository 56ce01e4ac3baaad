// The floats the `rays` harnesses decode from libFuzzer's bytes (rays_fuzz, mesh_rays_fuzz): values on a
// 1/16 lattice that line primitives and rays up, the special values that break arithmetic, and any bit
// pattern. fuzz/make_seeds.py writes seeds in this encoding (`tag`), so the two must change together.
#pragma once

#include <fuzzer/FuzzedDataProvider.h>

#include <bit>
#include <cstdint>
#include <iterator>
#include <limits>

#include "lancer/ray.hpp"
#include "lancer/vec.hpp"

namespace lancer::fuzz {

// Signed zeros, denormals, the float range's ends, overflow, NaN, and the ends of the coordinate domain
// (kCoordinateLimit = 2^60: a scene at its edge, the float just inside it).
inline constexpr float kSpecialValues[] = {
    0.0f,
    -0.0f,
    1.0f,
    -1.0f,
    std::numeric_limits<float>::denorm_min(),
    -std::numeric_limits<float>::denorm_min(),
    std::numeric_limits<float>::min(),
    std::numeric_limits<float>::max(),
    -std::numeric_limits<float>::max(),
    std::numeric_limits<float>::infinity(),
    -std::numeric_limits<float>::infinity(),
    std::numeric_limits<float>::quiet_NaN(),
    -std::numeric_limits<float>::quiet_NaN(),
    1e-30f,
    1e30f,
    -1e30f,
    0x1p24f,
    0x1p60f,
    -0x1p60f,
    0x1.fffffep+59f,
    0x1p-60f,
    0x1p127f,
    1e-7f,
    0.5f,
};
inline constexpr int kSpecialCount = static_cast<int>(std::size(kSpecialValues));

// One tag byte, then: a multiple of 1/16 in [-5, 5) (tag < 160), a special value, or any 32-bit pattern.
inline float next_float(FuzzedDataProvider& input) {
    const int tag = input.ConsumeIntegral<std::uint8_t>();
    if (tag < 160) return static_cast<float>(tag - 80) / 16.0f;
    if (tag < 160 + kSpecialCount) return kSpecialValues[tag - 160];
    return std::bit_cast<float>(input.ConsumeIntegral<std::uint32_t>());
}

inline Vec3f next_vec(FuzzedDataProvider& input) {
    const float x = next_float(input), y = next_float(input);
    return {x, y, next_float(input)};
}

// A ray of such floats: origin, direction, tnear, then tfar = +inf or one more float.
inline Ray next_any_ray(FuzzedDataProvider& input) {
    Ray ray;
    ray.origin = next_vec(input);
    ray.direction = next_vec(input);
    ray.tnear = next_float(input);
    ray.tfar = input.ConsumeBool() ? kInfinity : next_float(input);
    return ray;
}

}  // namespace lancer::fuzz
