// The watertight test leaves no gap: rays shot from inside a closed mesh exactly at its shared vertices and
// along its shared edges always hit (Woop, Benthin & Wald 2013). Moller-Trumbore's leaks are counted beside.
#include <gtest/gtest.h>

#include <array>
#include <limits>
#include <optional>

#include <random>

#include "accel/brute.hpp"
#include "core/exact_sign.hpp"
#include "core/intersect.hpp"
#include "lancer/generate.hpp"

namespace lancer {
namespace {

// A cube [-1, 1]^3 with two triangles per face, outward winding, vertices shared by index.
TriangleMesh make_cube() {
    TriangleMesh mesh;
    for (int i = 0; i < 8; ++i) {
        mesh.positions.push_back({(i & 1) ? 1.0f : -1.0f, (i & 2) ? 1.0f : -1.0f, (i & 4) ? 1.0f : -1.0f});
    }
    mesh.indices = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                    2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    return mesh;
}

// Targets on the surface: every vertex, and points along every edge (midpoints and random fractions).
std::vector<Vec3f> surface_targets(const TriangleMesh& mesh, std::mt19937& rng) {
    std::uniform_real_distribution<float> fraction(0.0f, 1.0f);
    std::vector<Vec3f> targets(mesh.positions.begin(), mesh.positions.end());
    for (std::size_t tri = 0; tri < mesh.triangle_count(); ++tri) {
        for (int corner = 0; corner < 3; ++corner) {
            const Vec3f a = mesh.positions[mesh.indices[3 * tri + corner]];
            const Vec3f b = mesh.positions[mesh.indices[3 * tri + (corner + 1) % 3]];
            targets.push_back(0.5f * (a + b));
            const float f = fraction(rng);
            targets.push_back((1.0f - f) * a + f * b);
        }
    }
    return targets;
}

struct LeakCount {
    std::size_t rays = 0, leaks = 0;
};

LeakCount count_leaks(const TriangleMesh& mesh, const std::vector<Vec3f>& origins, TriangleTest test) {
    std::mt19937 rng(11);
    const std::vector<Vec3f> targets = surface_targets(mesh, rng);
    const std::vector<Triangle> triangles = mesh.triangles();
    BruteAccel brute;
    brute.build({triangles, {}}, build_options(test));
    std::vector<Ray> rays;
    for (const Vec3f& origin : origins) {
        for (const Vec3f& target : targets)
            rays.push_back({origin, target - origin, 0.0f, kInfinity});
    }
    std::vector<std::uint8_t> occluded(rays.size());
    brute.occluded(rays, occluded);
    LeakCount count{rays.size(), 0};
    for (std::uint8_t hit : occluded)
        count.leaks += hit ? 0 : 1;
    return count;
}

const std::vector<Vec3f> kInteriorOrigins = {
    {0, 0, 0}, {0.1f, -0.2f, 0.3f}, {0.5f, 0.5f, 0.5f}, {-0.3f, 0.25f, -0.6f}, {1e-3f, 1e-3f, 0}};

// The axis permutation, exhaustively: kz last, {kx, ky, kz} a permutation of the axes with kx following kz
// cyclically (ky for a negative dominant component: the swap keeps the winding), and RayData choosing it for
// a direction dominant along kz of either sign.
TEST(Watertight, PermutationOfEveryDominantAxisAndSign) {
    for (int kz = 0; kz < 3; ++kz) {
        for (const bool negative : {false, true}) {
            const std::array<int, 3> axes = Watertight::permutation(kz, negative);
            EXPECT_EQ(axes[2], kz);
            EXPECT_EQ(axes[0] + axes[1] + axes[2], 3);
            EXPECT_NE(axes[0], axes[1]);
            EXPECT_EQ(axes[negative ? 1 : 0], (kz + 1) % 3) << kz << " " << negative;
            Vec3f direction(0.25f, -0.5f, 0.125f);
            direction[kz] = negative ? -2.0f : 2.0f;
            const Watertight::RayData data(Ray{{0, 0, 0}, direction, 0.0f, kInfinity});
            EXPECT_EQ(data.kz, kz);
            EXPECT_EQ(data.kx, axes[0]);
            EXPECT_EQ(data.ky, axes[1]);
        }
    }
}

// max_axis, computed without branches, against its rule written as branches (x if x >= y and x >= z, else y
// if y >= z, else z) on every triple of magnitudes from a set with ties, infinities and NaN.
TEST(Watertight, DominantAxisIsTheFirstOfTheLargestComponents) {
    const float values[] = {0.0f, 1.0f, 2.0f, kInfinity, std::numeric_limits<float>::quiet_NaN()};
    for (const float x : values) {
        for (const float y : values) {
            for (const float z : values) {
                int expected = 2;
                if (x >= y && x >= z) {
                    expected = 0;
                } else if (y >= z) {
                    expected = 1;
                }
                EXPECT_EQ(max_axis(Vec3f(x, y, z)), expected) << x << " " << y << " " << z;
            }
        }
    }
}

TEST(Watertight, NoLeakThroughSharedVerticesAndEdgesOfAnIcosphere) {
    const TriangleMesh sphere = make_icosphere(3);
    const LeakCount watertight = count_leaks(sphere, kInteriorOrigins, TriangleTest::Watertight);
    const LeakCount moller = count_leaks(sphere, kInteriorOrigins, TriangleTest::MollerTrumbore);
    std::printf("icosphere: %zu rays at vertices and edges; leaks: watertight %zu, moller-trumbore %zu\n",
                watertight.rays, watertight.leaks, moller.leaks);
    EXPECT_GT(watertight.rays, 40000u);
    EXPECT_EQ(watertight.leaks, 0u);
}

TEST(Watertight, NoLeakThroughTheEdgesAndCornersOfACube) {
    // Axis-aligned faces and edges: rays run exactly along the diagonals that split each face.
    const TriangleMesh cube = make_cube();
    const LeakCount watertight = count_leaks(cube, kInteriorOrigins, TriangleTest::Watertight);
    const LeakCount moller = count_leaks(cube, kInteriorOrigins, TriangleTest::MollerTrumbore);
    std::printf("cube: %zu rays at vertices and edges; leaks: watertight %zu, moller-trumbore %zu\n",
                watertight.rays, watertight.leaks, moller.leaks);
    EXPECT_EQ(watertight.leaks, 0u);
}

// Fuzz finding 22 (docs/robustness.md): a sliver 2^-126 wide, crossed 1 unit from the origin along a
// direction of 2^24, at t = 2^-24. One edge function is exactly zero, another underflowed to -0 in float, and
// the numerator's products fell below 2^-150: the float kernel said t = 0, a hit 1 unit from the sliver that
// brute force reported and the structures whose leaves exclude the origin did not. In double, t = 2^-24.
TEST(Watertight, DenormalEdgeFunctionsKeepTheirHitsT) {
    const Triangle sliver{Vec3f(0x1p-126f), {0x1p-126f, 1, 0}, {0, 0, 0}};
    const Ray ray{{-1, 0, 0}, {0x1p+24f, 0x1.4p-1f, 0x1.02fff8p-128f}, 0, kInfinity};
    TriangleHit hit{};
    ASSERT_TRUE(Watertight::intersect(Watertight::RayData(ray), sliver, ray.tnear, ray.tfar, hit));
    EXPECT_NEAR(hit.t, 0x1p-24f, 0x1p-40f);
    // The fuzzer's interval ends at 2^-126, before the sliver: no hit.
    EXPECT_FALSE(Watertight::intersect(Watertight::RayData(ray), sliver, -0x1.4d4d4cp-50f, 0x1p-126f, hit));
}

// Normal edge functions (a triangle 2^-30 across) whose numerator's products w z (z = 2^-80, the triangle
// just ahead of the origin) fall in the denormal range: the float t erred by up to 2^-10 of itself; the
// numerator below Watertight::kSmallNumerator is computed in double, and t is exact.
TEST(Watertight, ANumeratorInTheDenormalRangeIsComputedInDouble) {
    const float z = 0x1.234568p-80f, size = 0x1.6p-30f;
    const Triangle tiny{{-size, -size, z}, {size, -0x1.3p-31f, z}, {0x1.1p-32f, size, z}};
    const Ray ray{{0, 0, 0}, {0, 0, 1}, 0, kInfinity};
    TriangleHit hit{};
    ASSERT_TRUE(Watertight::intersect(Watertight::RayData(ray), tiny, ray.tnear, ray.tfar, hit));
    EXPECT_EQ(hit.t, z);
    EXPECT_GT(hit.u, 0.0f);
    EXPECT_GT(hit.v, 0.0f);
    EXPECT_LT(hit.u + hit.v, 1.0f);
}

// The ray the instance tests found (2026-11-29): from 10 units away, grazing a 0.15-unit triangle at about
// 1e-5 rad, so that its projection along the ray is 1.4e-6 wide, less than the rounding of the sheared
// vertices. The exact line crosses it at barycentrics (0.37, 0.46, 0.17); the float edge functions alone
// missed it. Moller-Trumbore decides such rays in double: both tests now report the same hit.
TEST(Watertight, AGrazingRayThroughAThinProjectionIsHitWhereTheExactLineCrossesIt) {
    const Triangle tri{{-0.33159408f, 2.3728423f, -0.3093877f},
                       {-0.4761646f, 2.4086459f, -0.34167776f},
                       {-0.43406615f, 2.3371084f, -0.23011614f}};
    const Ray ray{{-1.2560198f, 7.571823f, -8.824444f}, {0.8420782f, -5.1989574f, 8.530717f}, 0, kInfinity};
    TriangleHit expected{}, hit{};
    ASSERT_TRUE(MollerTrumbore::intersect(MollerTrumbore::RayData(ray), tri, ray.tnear, ray.tfar, expected));
    ASSERT_TRUE(Watertight::intersect(Watertight::RayData(ray), tri, ray.tnear, ray.tfar, hit));
    EXPECT_NEAR(hit.t, expected.t, 1e-6f * expected.t);
    EXPECT_NEAR(hit.u, expected.u, 1e-4f);
    EXPECT_NEAR(hit.v, expected.v, 1e-4f);
    EXPECT_NEAR(hit.u, 0.46f, 0.01f);
    EXPECT_NEAR(hit.v, 0.17f, 0.01f);
}

// An exact oracle for inputs that are integers below 2^38 with at most 24 significant bits (so exact floats):
// d . ((p - o) x (q - o)) in 128-bit integers, whose terms stay below 2^118.
__extension__ typedef __int128 Int128;  // GCC's and Clang's; ISO C++ has no 128-bit integer

int integer_side(const Vec3f& o, const Vec3f& d, const Vec3f& p, const Vec3f& q) {
    auto to_int = [](const Vec3f& v) {
        return std::array<Int128, 3>{static_cast<Int128>(v.x), static_cast<Int128>(v.y),
                                     static_cast<Int128>(v.z)};
    };
    const auto oi = to_int(o), di = to_int(d), pi = to_int(p), qi = to_int(q);
    std::array<Int128, 3> a{}, b{};
    for (int i = 0; i < 3; ++i)
        a[i] = pi[i] - oi[i], b[i] = qi[i] - oi[i];
    const Int128 value = di[0] * (a[1] * b[2] - a[2] * b[1]) + di[1] * (a[2] * b[0] - a[0] * b[2]) +
                         di[2] * (a[0] * b[1] - a[1] * b[0]);
    return (value > 0) - (value < 0);
}

// Integers of 1 to 24 significant bits shifted left by up to 14: values from 1 to 2^38 that meet with
// cancellation across many magnitudes, exact as floats.
float random_integer(std::mt19937& rng) {
    std::uniform_int_distribution<int> bits(1, 24), shift(0, 14), sign(0, 1);
    const int b = bits(rng);
    const auto mantissa = std::uniform_int_distribution<std::int64_t>(0, (std::int64_t{1} << b) - 1)(rng);
    return static_cast<float>(mantissa << shift(rng)) * (sign(rng) ? -1.0f : 1.0f);
}

TEST(ExactSign, LineEdgeSideIsTheExactSignOnIntegerInputs) {
    std::mt19937 rng(7);
    std::size_t zeros = 0, float_wrong = 0;
    for (int trial = 0; trial < 200000; ++trial) {
        auto vec = [&] { return Vec3f(random_integer(rng), random_integer(rng), random_integer(rng)); };
        const Vec3f o = vec(), p = vec();
        Vec3f d = vec(), q = vec();
        // A third of the edges made to meet the line (q on the plane of the line and p, up to the rounding
        // of a float q): exact zeros and tiny values of either sign.
        if (trial % 3 == 0) {
            std::uniform_int_distribution<int> step(-3, 3);
            q = p + static_cast<float>(step(rng)) * d + static_cast<float>(step(rng)) * (p - o);
            if (!(is_finite(q) && magnitude(q.x) < 0x1p38f && magnitude(q.y) < 0x1p38f &&
                  magnitude(q.z) < 0x1p38f))
                continue;
            q = Vec3f(std::round(q.x), std::round(q.y), std::round(q.z));
        }
        const int expected = integer_side(o, d, p, q);
        ASSERT_EQ(line_edge_side(o, d, p, q), expected) << "trial " << trial;
        zeros += expected == 0;
        const float in_float = dot(d, cross(p - o, q - o));
        float_wrong += (in_float > 0.0f ? 1 : in_float < 0.0f ? -1 : 0) != expected;
    }
    std::printf("exact zeros %zu, signs float got wrong %zu\n", zeros, float_wrong);
    // Not a degenerate sample: many exact zeros, and many signs that float arithmetic gets wrong.
    EXPECT_GT(zeros, 10000u);
    EXPECT_GT(float_wrong, 1000u);
}

// The 128-bit integer stage of line_edge_side against the exact sum, on the same float inputs: integer-valued
// rays and edges (a third of them meeting the line) scaled by powers of two from the subnormals to near the
// largest float, the positions and the direction by different ones, and coordinates moved apart by up to
// 2^30 so that some inputs spread beyond what the integers hold. Wherever the integers decide, both agree.
TEST(ExactSign, IntegerStageAgreesWithTheExactSumWhereverItDecides) {
    std::mt19937 rng(13);
    std::uniform_int_distribution<int> scale(-170, 60), spread(0, 30), coin(0, 1), step(-3, 3);
    std::size_t decided = 0, undecided = 0, zeros = 0;
    for (int trial = 0; trial < 300000; ++trial) {
        const int position_scale = scale(rng), direction_scale = scale(rng);
        const int position_spread = spread(rng) * coin(rng), direction_spread = spread(rng) * coin(rng);
        auto vec = [&] { return Vec3f(random_integer(rng), random_integer(rng), random_integer(rng)); };
        const Vec3f o = vec(), p = vec();
        Vec3f d = vec(), q = vec();
        if (trial % 3 == 0)
            q = p + static_cast<float>(step(rng)) * d + static_cast<float>(step(rng)) * (p - o);
        auto scaled = [&](Vec3f v, int by, int spread_by) {
            std::uniform_int_distribution<int> extra(0, spread_by);
            return Vec3f(std::ldexp(v.x, by + extra(rng)), std::ldexp(v.y, by + extra(rng)),
                         std::ldexp(v.z, by + extra(rng)));
        };
        const Vec3f so = scaled(o, position_scale, position_spread),
                    sp = scaled(p, position_scale, position_spread),
                    sq = scaled(q, position_scale, position_spread),
                    sd = scaled(d, direction_scale, direction_spread);
        if (!(is_finite(so) && is_finite(sp) && is_finite(sq) && is_finite(sd))) continue;
        const int expected = line_edge_side_in_expansions(so, sd, sp, sq);
        const std::optional<int> side = line_edge_side_in_integers(so, sd, sp, sq);
        if (!side) {
            ++undecided;
            continue;
        }
        ++decided;
        zeros += expected == 0;
        ASSERT_EQ(*side, expected) << "trial " << trial;
    }
    std::printf("decided %zu (exact zeros %zu), undecided %zu\n", decided, zeros, undecided);
    // Not a degenerate sample: both stages run, and many inputs meet the line exactly.
    EXPECT_GT(decided, 50000u);
    EXPECT_GT(zeros, 5000u);
    EXPECT_GT(undecided, 50000u);
}

// Terms that cancel exactly, a b c + a b c' - a b (c + c'), beside a fourth far below their rounding: the
// sum's sign is the fourth's. c and c' share an exponent and have 23-bit integer mantissas, so c + c' is a
// float; double arithmetic rounds the three products apart and loses the fourth.
TEST(ExactSign, ExactSumKeepsATermBelowTheOthersRounding) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> mantissa(1.0f, 2.0f);
    std::uniform_int_distribution<int> exponent(-40, 40), sign(0, 1), integer(1, (1 << 23) - 1);
    std::size_t double_wrong = 0;
    for (int trial = 0; trial < 100000; ++trial) {
        auto number = [&](int shift) {
            return std::ldexp(mantissa(rng), exponent(rng) + shift) * (sign(rng) ? -1.0f : 1.0f);
        };
        const float a = number(0), b = number(0);
        const int scale = exponent(rng);
        const float c = std::ldexp(static_cast<float>(integer(rng)), scale),
                    c_prime = std::ldexp(static_cast<float>(integer(rng)), scale), c_sum = c + c_prime;
        const float t = number(-60), u = number(-60), v = number(0);
        ExactSum<8> sum;
        sum.add_product(a, b, c);
        sum.add_product(a, b, c_prime);
        sum.add_product(-a, b, c_sum);
        sum.add_product(t, u, v);
        const double tiny = double(t) * u * v;
        ASSERT_EQ(sum.sign(), tiny > 0.0 ? 1 : -1) << "trial " << trial;
        const double ab = double(a) * b;
        const double in_double = ab * c + ab * c_prime - ab * c_sum + tiny;
        double_wrong += in_double == 0.0 || (in_double > 0.0) != (tiny > 0.0);
    }
    std::printf("signs double got wrong: %zu\n", double_wrong);
    EXPECT_GT(double_wrong, 1000u);
}

// The watertight test's decision is exact arithmetic's: hit where the line meets the closed triangle
// (no two edge signs opposite, not all zero), on integer vertices and rays, many of them through vertices
// and along edges, or grazing thin triangles. Its t is within rounding of the exact one where it hits.
TEST(Watertight, DecidesAsExactArithmeticOnIntegerVerticesAndRays) {
    std::mt19937 rng(9);
    std::uniform_int_distribution<int> small(-64, 64), choice(0, 3);
    std::size_t hits = 0, misses = 0, thin = 0;
    double max_t_error = 0.0;
    for (int trial = 0; trial < 300000; ++trial) {
        auto lattice = [&](int scale) {
            return Vec3f(static_cast<float>(small(rng) * scale), static_cast<float>(small(rng) * scale),
                         static_cast<float>(small(rng) * scale));
        };
        const Vec3f v0 = lattice(1024), v1 = lattice(1024);
        // Thin triangles: the third vertex near the line of the first two.
        const bool is_thin = choice(rng) == 0;
        const Vec3f v2 = is_thin ? v0 + 2.0f * (v1 - v0) + lattice(1) : lattice(1024);
        const Triangle tri{v0, v1, v2};
        // Targets on the triangle's vertices, edges and inside, as integer combinations; origins far away.
        const int pick = choice(rng);
        const Vec3f target = pick == 0 ? v0 : pick == 1 ? v1 + v2 : pick == 2 ? v0 + v1 + v2 : lattice(1024);
        const Vec3f origin = lattice(1 << 14);
        const Ray ray{origin,
                      pick == 1 || pick == 2 ? target - static_cast<float>(pick) * origin : target - origin,
                      -0x1p100f, kInfinity};
        if (!is_valid(ray) || (ray.direction.x == 0.0f && ray.direction.y == 0.0f && ray.direction.z == 0.0f))
            continue;
        const int s0 = integer_side(ray.origin, ray.direction, v1, v2);
        const int s1 = integer_side(ray.origin, ray.direction, v2, v0);
        const int s2 = integer_side(ray.origin, ray.direction, v0, v1);
        const bool expected = !((s0 < 0 || s1 < 0 || s2 < 0) && (s0 > 0 || s1 > 0 || s2 > 0)) &&
                              (s0 != 0 || s1 != 0 || s2 != 0);
        TriangleHit hit{};
        const bool actual = Watertight::intersect(Watertight::RayData(ray), tri, ray.tnear, ray.tfar, hit);
        ASSERT_EQ(actual, expected) << "trial " << trial;
        if (actual) {
            // The exact t = n . (v0 - o) / n . d, n = (v1 - v0) x (v2 - v0), in integers.
            auto to_int = [](const Vec3f& v) {
                return std::array<Int128, 3>{static_cast<Int128>(v.x), static_cast<Int128>(v.y),
                                             static_cast<Int128>(v.z)};
            };
            const auto a = to_int(v0), b = to_int(v1), c = to_int(v2), o = to_int(ray.origin),
                       d = to_int(ray.direction);
            std::array<Int128, 3> e1{}, e2{}, n{};
            for (int i = 0; i < 3; ++i)
                e1[i] = b[i] - a[i], e2[i] = c[i] - a[i];
            for (int i = 0; i < 3; ++i)
                n[i] = e1[(i + 1) % 3] * e2[(i + 2) % 3] - e1[(i + 2) % 3] * e2[(i + 1) % 3];
            Int128 numerator = 0, denominator = 0;
            for (int i = 0; i < 3; ++i)
                numerator += n[i] * (a[i] - o[i]), denominator += n[i] * d[i];
            const double exact_t = static_cast<double>(numerator) / static_cast<double>(denominator);
            max_t_error = std::max(max_t_error, std::abs(hit.t - exact_t) / std::abs(exact_t));
        }
        (expected ? hits : misses) += 1;
        thin += expected && is_thin;
    }
    std::printf("hits %zu (thin triangles %zu), misses %zu, largest relative error of t %g\n", hits, thin,
                misses, max_t_error);
    EXPECT_GT(hits, 50000u);
    EXPECT_GT(thin, 5000u);
    EXPECT_GT(misses, 50000u);
    EXPECT_LT(max_t_error, 0x1p-16);
}

}  // namespace
}  // namespace lancer
