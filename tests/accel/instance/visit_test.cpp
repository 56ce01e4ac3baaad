// The tests an instance visit starts with, one ray at a time and in lanes, against the one-ray forms they
// stand for: the world ray's validity (records.hpp), the map into the object's frame (affine.hpp,
// mapped_rays.hpp) and the object box cull (records.hpp, mapped_rays.hpp).
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "accel/instance/affine.hpp"
#include "accel/instance/mapped_rays.hpp"
#include "accel/instance/records.hpp"
#include "core/intersect.hpp"
#include "lancer/ray.hpp"
#include "lancer/transform.hpp"
#include "support/ray_sets.hpp"

namespace lancer::testing {
namespace {

// The floats the tests draw among beside ordinary numbers: zeros of both signs, subnormals, FLT_MAX,
// infinities and NaN.
constexpr float kSpecialFloats[] = {0.0f,
                                    -0.0f,
                                    1.0f,
                                    -2.5f,
                                    std::numeric_limits<float>::denorm_min(),
                                    -std::numeric_limits<float>::denorm_min(),
                                    std::numeric_limits<float>::max(),
                                    -std::numeric_limits<float>::max(),
                                    kInfinity,
                                    -kInfinity,
                                    std::numeric_limits<float>::quiet_NaN()};

// Floats drawn one in `one_in` among kSpecialFloats, the others ordinary numbers of either sign and of
// magnitude up to 2^`largest_exponent` (and down to its reciprocal).
class SpecialOrOrdinary {
  public:
    SpecialOrOrdinary(float largest_exponent, int one_in)
        : exponent_(-largest_exponent, largest_exponent), ordinary_(0, one_in - 1) {}
    float operator()(std::mt19937& rng) {
        return ordinary_(rng) != 0 ? unit_(rng) * std::exp2(exponent_(rng)) : kSpecialFloats[pick_(rng)];
    }

  private:
    std::uniform_real_distribution<float> unit_{-1.0f, 1.0f};
    std::uniform_real_distribution<float> exponent_;
    std::uniform_int_distribution<int> ordinary_;
    std::uniform_int_distribution<std::size_t> pick_{0, std::size(kSpecialFloats) - 1};
};

// The object box cull tests' boxes: in [-4, 4]^3, one in eight flat.
Box3f random_cull_box(std::mt19937& rng) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_int_distribution<int> pick(0, 7);
    Box3f box;
    box.extend(Vec3f(unit(rng), unit(rng), unit(rng)) * 4.0f);
    box.extend(Vec3f(unit(rng), unit(rng), unit(rng)) * 4.0f);
    if (pick(rng) == 0) box.hi.y = box.lo.y;
    return box;
}

// Their rays about `box`: from inside and outside, with zero direction components of both signs (infinite
// reciprocals; an origin in a face's plane makes a NaN plane), some aimed at a corner (where the exit
// widening decides), tnear < 0 and finite tfar; nullopt for a draw that is not valid.
std::optional<Ray> random_cull_ray(const Box3f& box, std::mt19937& rng) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_int_distribution<int> pick(0, 7);
    Ray ray{
        Vec3f(unit(rng), unit(rng), unit(rng)) * 8.0f, {unit(rng), unit(rng), unit(rng)}, 0.0f, kInfinity};
    for (int axis = 0; axis < 3; ++axis) {
        const int choice = pick(rng);
        if (choice == 0) ray.direction[axis] = 0.0f;
        if (choice == 1) ray.direction[axis] = -0.0f;
        if (choice <= 1 && pick(rng) < 4) ray.origin[axis] = pick(rng) < 4 ? box.lo[axis] : box.hi[axis];
    }
    if (pick(rng) < 2) {
        const Vec3f corner(pick(rng) < 4 ? box.lo.x : box.hi.x, pick(rng) < 4 ? box.lo.y : box.hi.y,
                           pick(rng) < 4 ? box.lo.z : box.hi.z);
        ray.direction = corner - ray.origin;
    }
    if (!is_valid(ray)) return std::nullopt;
    if (pick(rng) < 3) ray.tnear = -8.0f * std::fabs(unit(rng));
    if (pick(rng) < 3) ray.tfar = ray.tnear + 8.0f * std::fabs(unit(rng));
    return ray;
}

// The cull before an instance visit (top_level::crosses, SSE) answers as the scalar slab test it stands for
// (intersect_box) on every ray.
TEST(InstancedScene, ObjectBoxCullAnswersAsTheSlabTest) {
    std::mt19937 rng(61);
    std::size_t crossed = 0, missed = 0, differ = 0;
    for (int i = 0; i < 200000; ++i) {
        const Box3f box = random_cull_box(rng);
        const std::optional<Ray> ray = random_cull_ray(box, rng);
        if (!ray) continue;
        float t_entry = 0.0f, t_exit = 0.0f;
        const bool expected = intersect_box(SlabRay(*ray), box, ray->tnear, ray->tfar, t_entry, t_exit);
        (expected ? crossed : missed) += 1;
        differ += top_level::crosses(*ray, top_level::ObjectBox(box)) != expected ? 1 : 0;
    }
    EXPECT_EQ(differ, 0u);
    EXPECT_GT(crossed, 5000u);
    EXPECT_GT(missed, 20000u);
}

#if defined(__AVX2__)
// InverseAffine's steps on four rays in DoubleLanes (the packet walk's map_together): the map, then the
// far-origin move towards a centre, give each lane the bits of the one-ray steps in double. Random
// transforms, from the mild to the condition number's limit, and origins, directions and centres drawn among
// ordinary numbers, zeros of both signs, subnormals, FLT_MAX, infinities and NaN.
TEST(InstancedScene, LaneMapAnswersAsTheOneRayMap) {
    std::mt19937 rng(73);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_real_distribution<float> exponent(-30.0f, 30.0f);
    SpecialOrOrdinary draw(30.0f, 6);
    const auto coordinate = [&] { return draw(rng); };
    // A NaN's payload depends on which operand the compiler puts first; the walk leaves NaN lanes to the
    // one-ray visit, so only their being NaN must agree.
    const auto same_bits = [](double a, double b) {
        return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b) ||
               (std::isnan(a) && std::isnan(b));
    };
    std::size_t transforms = 0, lanes = 0, finite_moves = 0, differ = 0;
    for (int t = 0; t < 2000; ++t) {
        Transform transform;
        for (auto& row : transform.m)
            for (float& entry : row)
                entry = unit(rng) * std::exp2(exponent(rng) / 3.0f);
        std::string problem;
        const InverseAffine inverse = invert(transform, problem);
        if (!problem.empty()) continue;
        ++transforms;
        for (int group = 0; group < 16; ++group) {
            double origin[3][4], direction[3][4];
            for (int axis = 0; axis < 3; ++axis)
                for (int lane = 0; lane < 4; ++lane)
                    origin[axis][lane] = coordinate(), direction[axis][lane] = coordinate();
            const auto lanes_of = [](const double(&values4)[4]) {
                return DoubleLanes(_mm256_loadu_pd(values4));
            };
            const DoubleLanes origin_lanes[3] = {lanes_of(origin[0]), lanes_of(origin[1]),
                                                 lanes_of(origin[2])};
            const DoubleLanes direction_lanes[3] = {lanes_of(direction[0]), lanes_of(direction[1]),
                                                    lanes_of(direction[2])};
            DoubleLanes local_origin[3] = {origin_lanes[0], origin_lanes[1], origin_lanes[2]};
            DoubleLanes local_direction[3] = {direction_lanes[0], direction_lanes[1], direction_lanes[2]};
            inverse.map(origin_lanes, direction_lanes, local_origin, local_direction);
            const double centre[3] = {coordinate(), coordinate(), coordinate()};
            const DoubleLanes centre_lanes[3] = {DoubleLanes(centre[0]), DoubleLanes(centre[1]),
                                                 DoubleLanes(centre[2])};
            DoubleLanes moved[3] = {local_origin[0], local_origin[1], local_origin[2]};
            const DoubleLanes shift = InverseAffine::move_towards(centre_lanes, moved, local_direction);
            const auto lane_of = [](DoubleLanes values4, int lane) {
                double stored[4];
                _mm256_storeu_pd(stored, values4.lanes);
                return stored[lane];
            };
            for (int lane = 0; lane < 4; ++lane) {
                const double one_origin[3] = {origin[0][lane], origin[1][lane], origin[2][lane]};
                const double one_direction[3] = {direction[0][lane], direction[1][lane], direction[2][lane]};
                double expected_origin[3], expected_direction[3];
                inverse.map(one_origin, one_direction, expected_origin, expected_direction);
                double expected_moved[3] = {expected_origin[0], expected_origin[1], expected_origin[2]};
                const double expected_shift =
                    InverseAffine::move_towards(centre, expected_moved, expected_direction);
                differ += same_bits(lane_of(shift, lane), expected_shift) ? 0 : 1;
                for (int axis = 0; axis < 3; ++axis) {
                    differ += same_bits(lane_of(local_origin[axis], lane), expected_origin[axis]) ? 0 : 1;
                    differ +=
                        same_bits(lane_of(local_direction[axis], lane), expected_direction[axis]) ? 0 : 1;
                    differ += same_bits(lane_of(moved[axis], lane), expected_moved[axis]) ? 0 : 1;
                }
                ++lanes;
                finite_moves += std::isfinite(expected_shift) ? 1 : 0;
            }
        }
    }
    EXPECT_EQ(differ, 0u);
    EXPECT_GT(transforms, 1000u);
    EXPECT_GT(lanes, 16000u);
    EXPECT_GT(finite_moves, lanes / 4);
}

// A far lane's interval, moved in lanes (InverseAffine::move_interval on four rays, round_down_lanes and
// round_up_lanes), has the one-ray move's bits: on world intervals drawn among the special floats and
// ordinary numbers of every exponent, moved by shifts of any size, by shifts that leave the result a float
// (no rounding step), and by shifts that round it past the float range.
TEST(InstancedScene, LaneIntervalMoveAnswersAsTheOneRayMove) {
    std::mt19937 rng(79);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    std::uniform_real_distribution<double> exponent(-140.0, 140.0);
    std::uniform_int_distribution<int> kind(0, 7);
    SpecialOrOrdinary draw(90.0f, 8);
    const auto world_t = [&] { return draw(rng); };
    std::size_t lanes = 0, stepped = 0, differ = 0;
    for (int group = 0; group < 250000; ++group) {
        alignas(16) float tnear[4], tfar[4];
        alignas(32) double shift[4];
        for (int lane = 0; lane < 4; ++lane) {
            tnear[lane] = world_t(), tfar[lane] = world_t();
            const int shift_kind = kind(rng);
            if (shift_kind == 0) {
                shift[lane] = double(tnear[lane]) - double(world_t());  // a float left, when finite
            } else if (shift_kind == 1) {
                shift[lane] = double(tfar[lane]) - 0x1p129;  // tfar moved beyond FLT_MAX
            } else {
                shift[lane] = unit(rng) * std::exp2(exponent(rng));
            }
            if (!std::isfinite(shift[lane])) shift[lane] = 1.0;  // the walk moves by finite shifts only
        }
        __m128 moved_tnear, moved_tfar;
        InverseAffine::move_interval(_mm_load_ps(tnear), _mm_load_ps(tfar),
                                     DoubleLanes(_mm256_load_pd(shift)), moved_tnear, moved_tfar);
        alignas(16) float lane_tnear[4], lane_tfar[4];
        _mm_store_ps(lane_tnear, moved_tnear), _mm_store_ps(lane_tfar, moved_tfar);
        for (int lane = 0; lane < 4; ++lane) {
            float expected_tnear = 0.0f, expected_tfar = 0.0f;
            InverseAffine::move_interval(tnear[lane], tfar[lane], shift[lane], expected_tnear, expected_tfar);
            const auto same = [](float a, float b) {
                return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b) ||
                       (std::isnan(a) && std::isnan(b));
            };
            differ += same(lane_tnear[lane], expected_tnear) ? 0 : 1;
            differ += same(lane_tfar[lane], expected_tfar) ? 0 : 1;
            // A lane whose difference is not a float takes a rounding step one way or the other.
            stepped += double(expected_tfar) != double(tfar[lane]) - shift[lane] ? 1 : 0;
            ++lanes;
        }
    }
    EXPECT_EQ(differ, 0u);
    EXPECT_EQ(lanes, 1000000u);
    EXPECT_GT(stepped, lanes / 2);
}
#endif

#if defined(__AVX2__)
// The packet walk's object box cull in lanes (top_level::cull_in_lanes, over crosses_lanes) answers as the
// one-ray visit's, is_ordinary then crosses, lane by lane: 64 rays a box (random_cull_ray), some of their
// directions scaled out of the ordinary range and some origins moved far.
TEST(InstancedScene, ObjectBoxCullInLanesAnswersAsTheVisit) {
    std::mt19937 rng(67);
    std::uniform_int_distribution<int> pick(0, 15);
    std::size_t crossing = 0, culled = 0, unordinary = 0, differ = 0;
    for (int group = 0; group < 4000; ++group) {
        const Box3f box = random_cull_box(rng);
        top_level::InstanceRecord record;
        record.object_box = top_level::ObjectBox(box);
        record.object_centre = box.center();
        record.far_limit = 4.0f * std::max(max_component(box.extent()), 1.0f);
        top_level::MappedRays mapped;
        Ray rays[top_level::kPacketRays];
        for (std::size_t lane = 0; lane < top_level::kPacketRays; ++lane) {
            std::optional<Ray> ray;
            while (!ray)
                ray = random_cull_ray(box, rng);
            const int choice = pick(rng);
            if (choice == 0) ray->direction = ray->direction * 0x1p-40f;
            if (choice == 1) ray->direction = ray->direction * 0x1p40f;
            if (choice == 2) ray->origin = ray->origin + Vec3f(0.0f, 5.0f * record.far_limit, 0.0f);
            rays[lane] = *ray;
            for (int axis = 0; axis < 3; ++axis)
                mapped.origin[axis][lane] = ray->origin[axis],
                mapped.direction[axis][lane] = ray->direction[axis];
            mapped.tnear[lane] = ray->tnear, mapped.tfar[lane] = ray->tfar;
        }
        mapped.mapped = ~top_level::RayMask{0};
        top_level::cull_in_lanes(record, static_cast<int>(top_level::kPacketRays), mapped);
        for (std::size_t lane = 0; lane < top_level::kPacketRays; ++lane) {
            const bool ordinary = top_level::is_ordinary(rays[lane], record);
            const bool crosses = ordinary && top_level::crosses(rays[lane], record.object_box);
            unordinary += ordinary ? 0 : 1;
            (crosses ? crossing : culled) += ordinary ? 1 : 0;
            differ += ((mapped.culled >> lane) & 1) != (ordinary && !crosses) ? 1 : 0;
            differ += ((mapped.crossing >> lane) & 1) != (ordinary && crosses) ? 1 : 0;
        }
    }
    EXPECT_EQ(differ, 0u);
    EXPECT_GT(crossing, 20000u);
    EXPECT_GT(culled, 80000u);
    EXPECT_GT(unordinary, 30000u);
}
#endif

// The walk's validity test of a world ray (top_level::is_valid_ray, AVX2) answers as is_valid: on the
// hostile rays (NaN, infinite, zero directions, tnear > tfar) and on rays whose floats are drawn among
// zeros of both signs, subnormals, FLT_MAX, infinities, NaNs and ordinary numbers.
TEST(InstancedScene, RayValidityAnswersAsIsValid) {
    std::vector<Ray> rays = testing::hostile_rays(Box3f{{-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, 1.0f}}).rays;
    std::mt19937 rng(71);
    std::uniform_int_distribution<std::size_t> pick(0, std::size(kSpecialFloats) - 1);
    std::uniform_int_distribution<int> ordinary(0, 3);
    for (int i = 0; i < 200000; ++i) {
        float lanes[8];
        for (float& lane : lanes)
            lane = ordinary(rng) != 0 ? 1.0f + float(ordinary(rng)) : kSpecialFloats[pick(rng)];
        rays.push_back(std::bit_cast<Ray>(lanes));
    }
    std::size_t valid = 0, differ = 0;
    for (const Ray& ray : rays) {
        valid += is_valid(ray) ? 1 : 0;
        differ += top_level::is_valid_ray(ray) != is_valid(ray) ? 1 : 0;
    }
    EXPECT_EQ(differ, 0u);
    EXPECT_GT(valid, rays.size() / 10);
    EXPECT_LT(valid, rays.size() - rays.size() / 10);
}

}  // namespace
}  // namespace lancer::testing
