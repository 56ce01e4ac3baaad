// The packet structures against their single-ray siblings, bit for bit (bvh_packet / bvh, bvh8_packet / bvh8
// with the kernels of each instruction set, plucker_packet / plucker; the BVH pairs again built with spatial
// splits), and against brute force, on the batches that reach the packet code: tiles of a pinhole camera
// (coherent), rays of mixed direction signs (bvh_packet's fallback), batches that end in a partial packet,
// rays clipped by tnear and tfar, zero direction components and invalid rays inside coherent packets,
// incoherent streams of every size (bvh8_packet's hybrid walk and occlusion streams), shadow rays around the
// occlusion streams' capacities. The
// oracle test's ray sets have random directions, so most of their packets are incoherent: here the same
// adversarial sets are sorted by direction octant, which makes their packets coherent.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <random>

#include "accel/bvh/bvh8_packet.hpp"
#include "lancer/agreement.hpp"
#include "lancer/camera.hpp"
#include "lancer/generate.hpp"
#include "support/configurations.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

using testing::TestScene;

// `isa`: the instruction set of bvh8_packet's kernels (Auto: the widest available).
// `spatial_splits`: both structures built with bvh.spatial_splits.
// `interleaved_streams`: bvh8_packet's ray streams walk several at once (bvh.interleaved_streams=on), which
// its default leaves to trees of millions of primitives.
struct Pair {
    std::string_view packet, single;
    SimdIsa isa = SimdIsa::Auto;
    bool spatial_splits = false;
    bool interleaved_streams = false;

    [[nodiscard]] std::string label() const {
        std::string label(packet);
        if (isa != SimdIsa::Auto) label.append("_").append(isa_name(isa));
        if (spatial_splits) label.append("_spatial_splits");
        if (interleaved_streams) label.append("_interleaved_streams");
        return label;
    }
    [[nodiscard]] BuildOptions options(TriangleTest test) const {
        BuildOptions options = testing::Configuration{packet, spatial_splits, isa}.options(test);
        if (interleaved_streams) options.group<BvhOptions>().interleaved_streams = InterleavedStreams::On;
        return options;
    }
    [[nodiscard]] std::unique_ptr<Accel> make_packet() const { return make_accel(packet); }
};

std::vector<Pair> pairs() {
    std::vector<Pair> all = {{"bvh_packet", "bvh"},
                             {"bvh8_packet", "bvh8"},
                             {"plucker_packet", "plucker"},
                             {"bvh_packet", "bvh", SimdIsa::Auto, true},
                             {"bvh8_packet", "bvh8", SimdIsa::Auto, true},
                             {"bvh8_packet", "bvh8", SimdIsa::Auto, false, true}};
    // The AVX2 kernels where the widest are AVX-512: both paths are tested.
    if (isa_available(SimdIsa::Avx512)) {
        all.push_back({"bvh8_packet", "bvh8", SimdIsa::Avx2});
        all.push_back({"bvh8_packet", "bvh8", SimdIsa::Avx2, false, true});
    }
    return all;
}

void PrintTo(const Pair& pair, std::ostream* os) {
    *os << pair.label() << " against " << pair.single;
}

// Torus knot, icosphere and spheres; a plane of triangles whose shared edges make exact ties; and a finely
// tessellated sphere.
std::vector<TestScene> make_scenes() {
    std::vector<TestScene> all;
    TestScene mixed{"knot, icosphere and spheres", testing::knot_triangles(200), {}};
    make_icosphere(3, {0.5f, 0.2f, 0.1f}, 0.8f).append_triangles(mixed.triangles);
    std::mt19937 rng(6);
    std::uniform_real_distribution<float> unit(-1.5f, 1.5f);
    for (int i = 0; i < 20; ++i)
        mixed.spheres.push_back({{unit(rng), unit(rng), unit(rng)}, 0.1f + 0.05f * unit(rng), 0});
    all.push_back(std::move(mixed));
    all.push_back({"triangles of one plane", testing::planar_grid_triangles(30), {}});
    // Triangles smaller than a pixel of the test views: a leaf meets few rays of a group, and
    // bvh8_packet's Moller-Trumbore tests it a ray at a time (Bvh8PacketTraversal::test_rays).
    TestScene fine{"icosphere of 5120 triangles", {}, {}};
    make_icosphere(4, {0.1f, -0.2f, 0.3f}, 1.0f).append_triangles(fine.triangles);
    all.push_back(std::move(fine));
    return all;
}

const std::vector<TestScene>& scenes() {
    static const std::vector<TestScene> all = make_scenes();
    return all;
}

// Primary rays of a width x height view of `bounds`, in 8x8 tiles (tiles in scanline order), as lancer bench
// traces them; sizes that are not multiples of 8 leave partial tiles, so packets straddle tiles.
std::vector<Ray> tile_rays(const Box3f& bounds, int width, int height) {
    const PinholeCamera camera(canonical_view(bounds, width, height));
    std::vector<Ray> rays;
    for (int y0 = 0; y0 < height; y0 += 8) {
        for (int x0 = 0; x0 < width; x0 += 8) {
            for (int j = y0; j < std::min(height, y0 + 8); ++j) {
                for (int i = x0; i < std::min(width, x0 + 8); ++i)
                    rays.push_back(
                        camera.generate(static_cast<float>(i) + 0.5f, static_cast<float>(j) + 0.5f));
            }
        }
    }
    return rays;
}

// Rays grouped by the sign bits of their direction, in a stable order: consecutive rays then share them.
std::vector<Ray> sorted_by_octant(std::vector<Ray> rays) {
    const auto octant = [](const Ray& ray) {
        return (std::signbit(ray.direction.x) ? 1 : 0) | (std::signbit(ray.direction.y) ? 2 : 0) |
               (std::signbit(ray.direction.z) ? 4 : 0);
    };
    std::stable_sort(rays.begin(), rays.end(),
                     [&](const Ray& a, const Ray& b) { return octant(a) < octant(b); });
    return rays;
}

// Rays whose closest hit, through the batch call or the packet call (Accel::intersect_packet), or whose
// occlusion, differs in any bit between the two structures.
std::size_t bitwise_differences(const Accel& packet, const Accel& single, std::span<const Ray> rays) {
    std::vector<Hit> packet_hits(rays.size()), single_hits(rays.size());
    packet.intersect(rays, packet_hits);
    single.intersect(rays, single_hits);
    const std::vector<Hit> packet_call_hits = testing::intersect_in_packets(packet, rays);
    std::vector<std::uint8_t> packet_occluded(rays.size()), single_occluded(rays.size());
    packet.occluded(rays, packet_occluded);
    single.occluded(rays, single_occluded);
    std::size_t differences = 0;
    const auto same_hit = [](const Hit& a, const Hit& b) {
        return std::bit_cast<std::uint32_t>(a.t) == std::bit_cast<std::uint32_t>(b.t) && a.prim == b.prim &&
               std::bit_cast<std::uint32_t>(a.u) == std::bit_cast<std::uint32_t>(b.u) &&
               std::bit_cast<std::uint32_t>(a.v) == std::bit_cast<std::uint32_t>(b.v);
    };
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const bool same = same_hit(packet_hits[i], single_hits[i]) &&
                          same_hit(packet_call_hits[i], single_hits[i]) &&
                          packet_occluded[i] == single_occluded[i];
        differences += same ? 0 : 1;
    }
    return differences;
}

std::size_t hit_count(const Accel& accel, std::span<const Ray> rays) {
    std::vector<Hit> hits(rays.size());
    accel.intersect(rays, hits);
    return static_cast<std::size_t>(
        std::count_if(hits.begin(), hits.end(), [](const Hit& h) { return h.hit(); }));
}

class PacketTest : public ::testing::TestWithParam<Pair> {
  protected:
    // Calls check(packet, single, scene, test) for both triangle tests on every scene.
    template <class Check>
    void for_each_build(Check&& check) {
        for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            for (const TestScene& scene : scenes()) {
                const std::unique_ptr<Accel> packet = GetParam().make_packet();
                const std::unique_ptr<Accel> single = make_accel(GetParam().single);
                packet->build(scene.geometry(), GetParam().options(test));
                single->build(scene.geometry(), GetParam().options(test));
                SCOPED_TRACE(scene.name + (test == TriangleTest::Watertight ? ", watertight" : ", moller"));
                check(*packet, *single, scene, test);
            }
        }
    }
};

TEST_P(PacketTest, CameraTilesGiveTheSingleRayHitsBitForBit) {
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest) {
        const std::vector<Ray> rays = tile_rays(scene.geometry().bounds(), 93, 61);  // partial tiles
        EXPECT_EQ(bitwise_differences(packet, single, rays), 0u);
        EXPECT_GT(hit_count(packet, rays), rays.size() / 20);  // the view sees the scene
    });
}

TEST_P(PacketTest, MixedSignRaysFallBackWithTheSameHits) {
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest) {
        const testing::RaySet set = testing::random_rays(scene.geometry().bounds(), 3000, 7);
        EXPECT_EQ(bitwise_differences(packet, single, set.rays), 0u);
        EXPECT_GT(hit_count(packet, set.rays), set.rays.size() / 20);
    });
}

TEST_P(PacketTest, PartialPacketsAtTheEndOfABatch) {
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest) {
        const std::vector<Ray> rays = tile_rays(scene.geometry().bounds(), 64, 64);
        for (std::size_t size : {1u, 7u, 63u, 65u, 130u, 1000u}) {
            const std::span<const Ray> batch(rays.data() + 1000, size);  // from the middle of the view
            EXPECT_EQ(bitwise_differences(packet, single, batch), 0u) << size << " rays";
        }
    });
}

// The same tile rays with tnear and tfar cut around the surface: some hits are clipped away, some are not.
TEST_P(PacketTest, ClippedRaysInCoherentPackets) {
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest) {
        std::vector<Ray> rays = tile_rays(scene.geometry().bounds(), 64, 48);
        std::vector<Hit> unclipped(rays.size());
        single.intersect(rays, unclipped);
        std::mt19937 rng(9);
        std::uniform_real_distribution<float> fraction(0.5f, 1.5f);
        std::size_t clipped_away = 0;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            if (!unclipped[i].hit()) continue;
            // Mix rays whose interval holds their first hit with rays that start past it or end before it.
            rays[i].tnear = unclipped[i].t * (i % 3 == 0 ? fraction(rng) : 0.5f);
            rays[i].tfar = std::max(rays[i].tnear, unclipped[i].t * (i % 3 == 1 ? fraction(rng) : 2.0f));
        }
        std::vector<Hit> clipped(rays.size());
        single.intersect(rays, clipped);
        for (std::size_t i = 0; i < rays.size(); ++i)
            clipped_away += unclipped[i].hit() && clipped[i].prim != unclipped[i].prim ? 1 : 0;
        EXPECT_GT(clipped_away, 0u);
        EXPECT_EQ(bitwise_differences(packet, single, rays), 0u);
    });
}

// Zero direction components (rays along a face of every box) and invalid rays (NaN, zero direction) among
// the coherent rays of a packet: the invalid ones miss, the others keep their single-ray hits.
TEST_P(PacketTest, ZeroComponentsAndInvalidRaysInsideAPacket) {
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest) {
        const Box3f bounds = scene.geometry().bounds();
        std::vector<Ray> rays;
        for (int k = 0; k < 256; ++k) {
            const float s = (static_cast<float>(k) + 0.5f) / 256.0f;
            const Vec3f p = bounds.lo + s * (bounds.hi - bounds.lo);
            // Parallel to x, then in the xy plane, all with non-negative components.
            rays.push_back({{bounds.lo.x - 1.0f, p.y, p.z}, {1, 0, 0}, 0.0f, kInfinity});
            rays.push_back({{bounds.lo.x - 1.0f, bounds.lo.y, p.z}, {1, s, 0}, 0.0f, kInfinity});
            rays.push_back({{bounds.lo.x - 1.0f, p.y, bounds.hi.z}, {1, 0, 0}, 0.0f, kInfinity});
        }
        rays[5].direction = {std::nanf(""), 1, 0};
        rays[70] = {{0, 0, 0}, {0, 0, 0}, 0.0f, kInfinity};
        rays[140].tnear = 2.0f, rays[140].tfar = 1.0f;
        EXPECT_EQ(bitwise_differences(packet, single, rays), 0u);
        std::vector<Hit> hits(rays.size());
        packet.intersect(rays, hits);
        EXPECT_FALSE(hits[5].hit() || hits[70].hit() || hits[140].hit());
    });
}

// Incoherent rays in the order a path tracer's bounce makes them: random directions from origins in a small
// region, with the hostile rays (NaN, infinite, zero or denormal direction, tnear > tfar), rays with a zero
// direction component, rays starting behind their origin (tnear < 0) and clipped rays spread through the
// stream, so that they share packets (of the interval cull or the hybrid walk) with ordinary rays.
std::vector<Ray> incoherent_stream(const Box3f& bounds, std::size_t count, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), share(0.0f, 1.0f);
    const Vec3f centre = 0.5f * (bounds.lo + bounds.hi), extent = bounds.hi - bounds.lo;
    const std::vector<Ray> hostile = testing::hostile_rays(bounds).rays;
    std::vector<Ray> rays;
    rays.reserve(count);
    for (std::size_t i = 0; i < count; ++i) {
        const float kind = share(rng);
        if (kind < 0.02f) {
            rays.push_back(hostile[i % hostile.size()]);
            continue;
        }
        Ray ray{centre + 0.2f * Vec3f(unit(rng) * extent.x, unit(rng) * extent.y, unit(rng) * extent.z),
                {unit(rng), unit(rng), unit(rng)},
                0.0f,
                kInfinity};
        if (kind < 0.04f) ray.direction[static_cast<int>(i % 3)] = 0.0f;
        if (kind > 0.97f) ray.tnear = -0.5f * share(rng);
        if (kind > 0.94f && kind <= 0.97f) ray.tfar = 0.3f * share(rng) * extent.x;
        rays.push_back(ray);
    }
    return rays;
}

// Batches of every size around the packet's and the lane group's (1, 15, 16, 17, 63, 65, 4096 rays) of
// incoherent rays: the single-ray answers, bit for bit, through the batch, packet and occlusion calls.
TEST_P(PacketTest, IncoherentStreamsOfEverySize) {
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest) {
        const std::vector<Ray> rays = incoherent_stream(scene.geometry().bounds(), 4096 + 200, 21);
        for (std::size_t size : {1u, 15u, 16u, 17u, 63u, 65u, 4096u}) {
            const std::span<const Ray> batch(rays.data() + 100, size);
            EXPECT_EQ(bitwise_differences(packet, single, batch), 0u) << size << " rays";
        }
        EXPECT_GT(hit_count(packet, rays), rays.size() / 10);
    });
}

// Shadow rays as a renderer makes them: from points spread over the scene towards two lights beyond
// opposite corners, unnormalised, ending just short of the light. Consecutive rays alternate between the
// lights, so that two octants fill their streams (bvh8_packet's occlusion stream, 32 rays with the AVX2
// kernels and 64 with AVX-512) in turn, and every few rays is one the stream does not take: hostile, a zero
// direction component, or starting behind its origin (tnear < 0).
std::vector<Ray> shadow_rays(const Box3f& bounds, std::size_t count, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const Vec3f extent = bounds.hi - bounds.lo;
    const std::array<Vec3f, 2> lights = {bounds.hi + 0.5f * extent, bounds.lo - 0.5f * extent};
    const std::vector<Ray> hostile = testing::hostile_rays(bounds).rays;
    std::vector<Ray> rays;
    rays.reserve(count);
    for (std::size_t i = 0; i < count; ++i) {
        if (i % 29 == 28) {
            rays.push_back(hostile[i % hostile.size()]);
            continue;
        }
        const Vec3f origin =
            bounds.lo + Vec3f(unit(rng) * extent.x, unit(rng) * extent.y, unit(rng) * extent.z);
        Ray ray{origin, lights[i % 2] - origin, 1e-4f, 1.0f - 1e-4f};
        if (i % 31 == 30) ray.direction[static_cast<int>(i % 3)] = 0.0f;
        if (i % 37 == 36) ray.tnear = -0.1f;
        rays.push_back(ray);
    }
    return rays;
}

// Occlusion batches around the occlusion stream's capacities, each ray answered as bvh8 answers it; some
// rays occluded and some free on every scene.
TEST_P(PacketTest, ShadowRayStreamsAroundTheirCapacity) {
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest) {
        const std::vector<Ray> rays = shadow_rays(scene.geometry().bounds(), 2000, 23);
        for (std::size_t size : {1u, 31u, 32u, 33u, 63u, 64u, 65u, 127u, 128u, 129u, 2000u}) {
            const std::span<const Ray> batch(rays.data(), size);
            EXPECT_EQ(bitwise_differences(packet, single, batch), 0u) << size << " rays";
        }
        std::vector<std::uint8_t> occluded(rays.size());
        packet.occluded(rays, occluded);
        const auto blocked = static_cast<std::size_t>(std::count(occluded.begin(), occluded.end(), 1));
        EXPECT_GT(blocked, 0u);
        EXPECT_LT(blocked, rays.size());
    });
}

// A million incoherent rays through bvh8_packet with each instruction set's kernels, both triangle tests and
// its streams one at a time and interleaved: bvh8's answers bit for bit.
TEST(Bvh8Packet, AMillionIncoherentRaysGiveBvh8sAnswers) {
    const TestScene& scene = scenes()[0];
    const std::vector<Ray> rays =
        incoherent_stream(scene.geometry().bounds(), 1'000'000 / testing::kSanitizedShare, 22);
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        Bvh8Accel single;
        single.build(scene.geometry(), build_options(test));
        for (SimdIsa isa : available_isas()) {
            for (InterleavedStreams interleaved : {InterleavedStreams::Off, InterleavedStreams::On}) {
                BuildOptions options = build_options(test);
                options.isa = isa;
                options.group<BvhOptions>().interleaved_streams = interleaved;
                Bvh8PacketAccel packet;
                packet.build(scene.geometry(), options);
                EXPECT_EQ(bitwise_differences(packet, single, rays), 0u)
                    << isa_name(isa)
                    << (interleaved == InterleavedStreams::On ? ", interleaved streams" : "");
            }
        }
    }
}

// The oracle's adversarial sets (vertex and edge rays, axis-parallel rays, clipped rays), sorted so that
// their packets are coherent: the same hits as `single` bit for bit, and as brute force.
TEST_P(PacketTest, AdversarialSetsSortedIntoCoherentPackets) {
    static testing::BruteForceCache brute_force;  // shared by the structures, run in one process
    for_each_build([](const Accel& packet, const Accel& single, const TestScene& scene, TriangleTest test) {
        const auto scene_index = static_cast<std::size_t>(&scene - scenes().data());
        const Box3f bounds = scene.geometry().bounds();
        const std::vector<testing::RaySet> sets = {testing::vertex_and_edge_rays(scene.triangles, 3000, 12),
                                                   testing::axis_parallel_rays(bounds, 3000, 13),
                                                   testing::clipped_rays(bounds, 2000, 14)};
        for (std::size_t set_index = 0; set_index < sets.size(); ++set_index) {
            const testing::RaySet& set = sets[set_index];
            const std::vector<Ray> rays = sorted_by_octant(set.rays);
            EXPECT_EQ(bitwise_differences(packet, single, rays), 0u) << set.name;
            const std::vector<Hit>& expected =
                brute_force.hits(scene_index, set_index, test, scene.geometry(), rays);
            std::vector<Hit> hits(rays.size());
            packet.intersect(rays, hits);
            const Agreement agreement = compare_hits(rays, expected, hits);
            EXPECT_EQ(agreement.mismatches, 0u) << set.name << ": " << agreement.summary();
            EXPECT_GT(agreement.hits, rays.size() / 50) << set.name;
        }
    });
}

TEST_P(PacketTest, CountersSeeEveryRayOfEveryPacket) {
    const TestScene scene = scenes()[0];
    const std::unique_ptr<Accel> packet = GetParam().make_packet();
    packet->build(scene.geometry(), GetParam().options(TriangleTest::MollerTrumbore));
    const std::vector<Ray> rays = tile_rays(scene.geometry().bounds(), 40, 30);
    std::vector<Hit> hits(rays.size()), counted(rays.size());
    packet->intersect(rays, hits);
    TraversalCounters counters;
    packet->intersect(rays, counted, &counters);
    EXPECT_EQ(counters.rays, rays.size());
    EXPECT_GT(counters.nodes_visited, 0u);
    EXPECT_GT(counters.prims_tested, 0u);
    for (std::size_t i = 0; i < hits.size(); ++i)
        ASSERT_EQ(hits[i].prim, counted[i].prim);
    // The packet call counts its rays too: 50 from the first that hits.
    const auto first_hit = static_cast<std::size_t>(
        std::find_if(hits.begin(), hits.end(), [](const Hit& hit) { return hit.hit(); }) - hits.begin());
    ASSERT_LE(first_hit + 50, rays.size());
    RayPacket rays_packet;
    HitPacket hits_packet;
    rays_packet.size = 50;
    for (int lane = 0; lane < rays_packet.size; ++lane)
        rays_packet.set(lane, rays[first_hit + static_cast<std::size_t>(lane)]);
    TraversalCounters packet_counters;
    packet->intersect_packet(rays_packet, hits_packet, &packet_counters);
    EXPECT_EQ(packet_counters.rays, 50u);
    EXPECT_GT(packet_counters.nodes_visited, 0u);
}

// copy_four writes lanes [first, first + 4) as the records hit() gives, bit for bit, and nothing around them.
// A merged leaf's header (bvh.leaf_boxes) lets each ray of a stream test only the blocks whose boxes it
// crosses: 32 small triangles in a row along x make one leaf of 4 blocks (the SAH orders them along the
// row), and two rays of opposite octants (so that each takes a stream) through one triangle each test one
// block each, for closest hits and for occlusion; without the header they tested up to all 32 triangles. Auto
// gives so small a geometry the header.
TEST(Bvh8Packet, StreamsTestOnlyTheBlocksARayCrosses) {
    std::vector<Triangle> triangles;
    for (int i = 0; i < 32; ++i) {
        const auto x = static_cast<float>(i);
        triangles.push_back({{x, 0.0f, 0.0f}, {x + 0.5f, 0.0f, 0.0f}, {x, 0.5f, 0.0f}});
    }
    const std::vector<Ray> rays = {{{3.1f, 0.1f, 1.0f}, {0.0f, 0.0f, -1.0f}, 0.0f, kInfinity},
                                   {{29.1f, 0.1f, -1.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, kInfinity}};
    for (const LeafBoxes boxes : {LeafBoxes::Auto, LeafBoxes::On, LeafBoxes::Off}) {
        BuildOptions options;
        options.group<BvhOptions>().leaf_boxes = boxes;
        Bvh8PacketAccel packet;
        packet.build({triangles, {}}, options);
        std::vector<Hit> hits(rays.size());
        std::vector<std::uint8_t> occluded(rays.size());
        TraversalCounters closest, any;
        packet.intersect(rays, hits, &closest);
        packet.occluded(rays, occluded, &any);
        EXPECT_EQ(hits[0].prim, 3u);
        EXPECT_EQ(hits[1].prim, 29u);
        EXPECT_EQ(occluded, std::vector<std::uint8_t>({1, 1}));
        // Without the header, occlusion stops at the block that holds the hit: ray 0's first, ray 1's last.
        const bool headers = boxes != LeafBoxes::Off;
        EXPECT_EQ(closest.prims_tested, headers ? 2u * 8 : 2u * 32);
        EXPECT_EQ(any.prims_tested, headers ? 2u * 8 : 8u + 32);
    }
}

TEST(PacketCall, HitPacketCopiesFourRecords) {
    HitPacket packet;
    for (int lane = 0; lane < RayPacket::kMaxSize; ++lane)
        packet.set(lane, {1.5f * static_cast<float>(lane), lane % 7 == 0 ? -1 : lane, 0.25f, -0.0f});
    for (const int first : {0, 4, 29, 60}) {
        std::array<Hit, 6> out;
        out.fill({-2.0f, -3, -4.0f, -5.0f});
        packet.copy_four(first, out.data() + 1);
        EXPECT_EQ(out[0].prim, -3);
        EXPECT_EQ(out[5].prim, -3);
        for (int k = 0; k < 4; ++k) {
            const Hit expected = packet.hit(first + k);
            EXPECT_EQ(std::memcmp(&out[static_cast<std::size_t>(k) + 1], &expected, sizeof(Hit)), 0)
                << "lane " << first + k;
        }
    }
}

// A packet holds 0 to 64 rays: any other size is refused, naming it, before a lane is read.
TEST(PacketCall, RefusesASizeOutsideThePacket) {
    const TestScene scene = scenes()[0];
    const std::unique_ptr<Accel> accel = make_accel("bvh8_packet");
    accel->build(scene.geometry(), {});
    RayPacket rays;
    HitPacket hits;
    rays.size = 0;
    EXPECT_NO_THROW(accel->intersect_packet(rays, hits));
    for (const int size : {-1, RayPacket::kMaxSize + 1}) {
        rays.size = size;
        try {
            accel->intersect_packet(rays, hits);
            ADD_FAILURE() << "size " << size << " accepted";
        } catch (const std::invalid_argument& error) {
            EXPECT_NE(std::string(error.what()).find(std::to_string(size)), std::string::npos)
                << error.what();
        }
    }
}

// bvh8_packet runs the widest kernels by default, and those asked for: 16 lanes with AVX-512, 8 with AVX2.
TEST(Bvh8Packet, RunsTheKernelsOfTheInstructionSetAskedFor) {
    const TestScene scene = scenes()[0];
    Bvh8PacketAccel widest;
    widest.build(scene.geometry(), build_options(TriangleTest::MollerTrumbore));
    EXPECT_EQ(widest.lane_count(), isa_available(SimdIsa::Avx512) ? 16 : 8);
    for (SimdIsa isa : available_isas()) {
        BuildOptions options = build_options(TriangleTest::MollerTrumbore);
        options.isa = isa;
        Bvh8PacketAccel accel;
        accel.build(scene.geometry(), options);
        EXPECT_EQ(accel.lane_count(), isa == SimdIsa::Avx512 ? 16 : 8) << isa_name(isa);
    }
    if (!isa_available(SimdIsa::Avx512)) {
        BuildOptions options = build_options(TriangleTest::MollerTrumbore);
        options.isa = SimdIsa::Avx512;
        Bvh8PacketAccel accel;
        EXPECT_THROW(accel.build(scene.geometry(), options), std::invalid_argument);
    }
}

INSTANTIATE_TEST_SUITE_P(Packets, PacketTest, ::testing::ValuesIn(pairs()),
                         [](const auto& param_info) { return param_info.param.label(); });

}  // namespace
}  // namespace lancer
