// The exact sign of a small polynomial in float inputs, for the watertight test's rays that its float edge
// functions cannot decide (docs/numerical-contract.md, "Triangle tests"). A product of two floats is exact in
// double (24 + 24 significand bits); a third factor is made exact by the two-product (Ogita, Rump & Oishi,
// "Accurate Sum and Dot Product", 2005: the fused multiply-add returns the rounding error), and the terms
// are summed exactly into a nonoverlapping expansion whose largest component carries the sign (Shewchuk,
// "Adaptive Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997, section 2).
// Host-device: the GPU decides the same rays with the same source (docs/cuda.md).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <optional>

#include "core/host_device.hpp"
#include "core/isa_namespace.hpp"
#include "lancer/vec.hpp"

namespace lancer {
// Per instruction set (core/isa_namespace.hpp): the kernels compiled for AVX-512 call these too.
inline namespace LANCER_ISA_NAMESPACE {

// An exact sum of up to Capacity doubles, kept as a nonoverlapping expansion of increasing magnitude with
// its zero components dropped. No term may overflow: products of three floats stay below 2^387, and their
// rounding errors above 2^-1022 (a float is at least 2^-149).
template <int Capacity>
class ExactSum {
  public:
    // Shewchuk's Grow-Expansion with zero elimination: each component in turn joins the running sum, whose
    // rounding error Two-Sum keeps (Knuth, TAOCP vol. 2, 4.2.2).
    LANCER_HOST_DEVICE void add(double term) {
        double sum = term;
        int kept = 0;
        for (int i = 0; i < count_; ++i) {
            const double component = component_[i];
            const double rounded = sum + component;
            const double sum_part = rounded - component;
            const double error = (sum - sum_part) + (component - (rounded - sum_part));
            sum = rounded;
            if (error != 0.0) component_[kept++] = error;
        }
        if (sum != 0.0) component_[kept++] = sum;
        count_ = kept;
    }

    // a b c exactly, as two terms: a b is exact in double.
    LANCER_HOST_DEVICE void add_product(float a, float b, float c) {
        const double ab = double(a) * double(b);
        const double abc = ab * double(c);
#if defined(__CUDA_ARCH__)
        add(fma(ab, double(c), -abc));
#else
        add(std::fma(ab, double(c), -abc));
#endif
        add(abc);
    }

    // -1, 0 or 1: the sign of the largest component, the last one kept.
    [[nodiscard]] LANCER_HOST_DEVICE int sign() const {
        if (count_ == 0) return 0;
        return component_[count_ - 1] > 0.0 ? 1 : -1;
    }

  private:
    double component_[Capacity] = {};
    int count_ = 0;
};

// One float as sign significand 2^exponent, the significand an integer below 2^24 (0 for a zero).
struct FloatParts {
    std::int64_t significand;
    int exponent;
};
[[nodiscard]] inline FloatParts float_parts(float x) {
    const auto bits = std::bit_cast<std::uint32_t>(x);
    const int biased = static_cast<int>((bits >> 23) & 0xff);
    const auto fraction = static_cast<std::int64_t>(bits & 0x7fffff);
    const std::int64_t significand = biased == 0 ? fraction : fraction | (std::int64_t{1} << 23);
    return {bits >> 31 ? -significand : significand, biased == 0 ? -149 : biased - 150};
}

// The sign of d . ((p - o) x (q - o)) in 128-bit integers, or nothing. The positions o, p, q are integers
// times 2^(their least exponent), and d is one times 2^(its least): a positive factor that leaves the sign
// alone. With S and S_d the spans of exponents among the nonzero positions and direction components, the
// differences stay below 2^(25 + S), the cross product's components below 2^(51 + 2 S), and the sum of
// three products below 2^(77 + 2 S + S_d): exact when 2 S + S_d <= 49 (and S_d <= 39, for d's integers to
// fit in 64 bits). Inputs of one object and a ray near it meet that; inputs beyond it, or not finite, are
// left to the exact sum below. Host only: on the GPU it raised the watertight batch kernels' registers
// (docs/cuda.md, "Registers").
[[nodiscard]] inline std::optional<int> line_edge_side_in_integers(const Vec3f& o, const Vec3f& d,
                                                                   const Vec3f& p, const Vec3f& q) {
    __extension__ typedef __int128 Int128;  // GCC's and Clang's; ISO C++ has no 128-bit integer
    const FloatParts positions[9] = {float_parts(o.x), float_parts(o.y), float_parts(o.z),
                                     float_parts(p.x), float_parts(p.y), float_parts(p.z),
                                     float_parts(q.x), float_parts(q.y), float_parts(q.z)};
    const FloatParts direction[3] = {float_parts(d.x), float_parts(d.y), float_parts(d.z)};
    // The least and greatest exponents of the nonzero parts, {1000, -1000} if all are zero. Infinities and
    // NaNs have the exponent 105, beyond any finite float's 104.
    struct Span {
        int least = 1000, greatest = -1000;
    };
    auto span = [](const FloatParts* parts, int count) {
        Span s;
        for (int i = 0; i < count; ++i) {
            if (parts[i].significand == 0) continue;
            s.least = parts[i].exponent < s.least ? parts[i].exponent : s.least;
            s.greatest = parts[i].exponent > s.greatest ? parts[i].exponent : s.greatest;
        }
        return s;
    };
    const Span position_span = span(positions, 9), direction_span = span(direction, 3);
    if (position_span.greatest < position_span.least || direction_span.greatest < direction_span.least)
        return 0;  // every position or every direction component zero: so is the product
    const int spread = position_span.greatest - position_span.least,
              direction_spread = direction_span.greatest - direction_span.least;
    if (position_span.greatest > 104 || direction_span.greatest > 104 || 2 * spread + direction_spread > 49 ||
        direction_spread > 39)
        return std::nullopt;
    const int least = position_span.least, least_direction = direction_span.least;
    auto integer = [](const FloatParts& part, int lowest) {
        return part.significand == 0 ? std::int64_t{0}
                                     : part.significand * (std::int64_t{1} << (part.exponent - lowest));
    };
    std::int64_t a[3], b[3];
    for (int i = 0; i < 3; ++i) {
        const std::int64_t origin = integer(positions[i], least);
        a[i] = integer(positions[3 + i], least) - origin;
        b[i] = integer(positions[6 + i], least) - origin;
    }
    const Int128 value =
        Int128(integer(direction[0], least_direction)) * (Int128(a[1]) * b[2] - Int128(a[2]) * b[1]) +
        Int128(integer(direction[1], least_direction)) * (Int128(a[2]) * b[0] - Int128(a[0]) * b[2]) +
        Int128(integer(direction[2], least_direction)) * (Int128(a[0]) * b[1] - Int128(a[1]) * b[0]);
    return (value > 0) - (value < 0);
}

// The sign of d . ((p - o) x (q - o)) for any finite inputs, expanded so that every term is a product of
// three inputs, d . (p x q) + d . (o x p) - d . (o x q), and summed exactly.
[[nodiscard]] LANCER_HOST_DEVICE inline int line_edge_side_in_expansions(const Vec3f& o, const Vec3f& d,
                                                                         const Vec3f& p, const Vec3f& q) {
    ExactSum<36> sum;
    // a . (b x c) = sum over the cyclic (i, j, k) of a_i (b_j c_k - b_k c_j).
    auto add_triple_product = [&sum](const Vec3f& a, const Vec3f& b, const Vec3f& c, float sign) {
        for (int i = 0; i < 3; ++i) {
            const int j = (i + 1) % 3, k = (i + 2) % 3;
            sum.add_product(sign * a[i], b[j], c[k]);
            sum.add_product(-sign * a[i], b[k], c[j]);
        }
    };
    add_triple_product(d, p, q, 1.0f);
    add_triple_product(d, o, p, 1.0f);
    add_triple_product(d, o, q, -1.0f);
    return sum.sign();
}

// The sign of d . ((p - o) x (q - o)), exactly: the side of the line o + t d on which the edge p q passes
// (the Plucker product of the line and the edge, up to its positive factors). First in double, whose result
// decides where it exceeds its error bound: the differences are rounded once each (2^-53 of themselves), the
// cross and dot products add five roundings, under 8 2^-53 of the sum of the terms' magnitudes in all, and
// 2^-49 covers that and the bound's own rounding (a filtered predicate, as Shewchuk's orient3d). Within the
// bound, on the host in 128-bit integers where the inputs' exponents allow, which costs a fraction of the
// exact sum (docs/numerical-contract.md, "Triangle tests"), else by the exact sum. Both are exact, so the
// GPU, which takes the exact sum alone, decides every ray as the CPU does.
[[nodiscard]] LANCER_HOST_DEVICE inline int line_edge_side(const Vec3f& o, const Vec3f& d, const Vec3f& p,
                                                           const Vec3f& q) {
    const double ax = double(p.x) - o.x, ay = double(p.y) - o.y, az = double(p.z) - o.z;
    const double bx = double(q.x) - o.x, by = double(q.y) - o.y, bz = double(q.z) - o.z;
    const double x_term = double(d.x) * (ay * bz - az * by), y_term = double(d.y) * (az * bx - ax * bz),
                 z_term = double(d.z) * (ax * by - ay * bx);
    const double value = x_term + y_term + z_term;
    const double bound = 0x1p-49 * (magnitude(double(d.x)) * (magnitude(ay * bz) + magnitude(az * by)) +
                                    magnitude(double(d.y)) * (magnitude(az * bx) + magnitude(ax * bz)) +
                                    magnitude(double(d.z)) * (magnitude(ax * by) + magnitude(ay * bx)));
    if (value > bound) return 1;
    if (value < -bound) return -1;
#if !defined(__CUDA_ARCH__)
    if (const std::optional<int> side = line_edge_side_in_integers(o, d, p, q)) return *side;
#endif
    return line_edge_side_in_expansions(o, d, p, q);
}

}  // namespace LANCER_ISA_NAMESPACE
}  // namespace lancer
