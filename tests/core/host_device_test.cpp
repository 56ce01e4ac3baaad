// The helpers that kernels shared by the CPU and the GPU use instead of the standard library
// (core/host_device.hpp): each must answer as the standard function it stands for, bit for bit.
#include "core/host_device.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "lancer/ray.hpp"

namespace lancer {
namespace {

bool same_bits(float a, float b) {
    return std::memcmp(&a, &b, sizeof(float)) == 0;
}

const float kValues[] = {0.0f, -0.0f, 1.5f, -2.0f, 0x1p-149f, kInfinity, -kInfinity, std::nanf("")};

TEST(HostDevice, MinAndMaxKeepStdMinAndMaxOperandOrderWithNaNAndZeros) {
    for (const float a : kValues) {
        for (const float b : kValues) {
            EXPECT_TRUE(same_bits(min_of(a, b), std::min(a, b))) << a << ", " << b;
            EXPECT_TRUE(same_bits(max_of(a, b), std::max(a, b))) << a << ", " << b;
        }
    }
    EXPECT_EQ(min_of(3u, 7u), 3u);
    EXPECT_EQ(min_of(0xFFFFFFFFu, 7u), 7u);
}

TEST(HostDevice, IsNanAndMagnitudeAreTheStandardOnes) {
    for (const float a : kValues) {
        EXPECT_EQ(is_nan(a), std::isnan(a)) << a;
        EXPECT_TRUE(same_bits(magnitude(a), std::fabs(a))) << a;
    }
}

TEST(HostDevice, InversePowersOfTwoAreExact) {
    for (int level = 0; level <= 126; ++level)
        EXPECT_EQ(inverse_power_of_two(level), std::ldexp(1.0f, -level)) << level;
}

}  // namespace
}  // namespace lancer
