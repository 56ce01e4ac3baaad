// Accel::update and World::update_vertices (docs/accel/refit.md): after every update every structure agrees
// with the brute-force oracle on the moved mesh, refitting back to the rest pose gives the first answers bit
// for bit, the SAH watch rebuilds past its threshold, and bad input leaves the world as it was.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>

#include "accel/brute.hpp"
#include "accel/build_util.hpp"
#include "accel/bvh/bvh_wide.hpp"
#include "lancer/agreement.hpp"
#include "lancer/animate.hpp"
#include "lancer/generate.hpp"
#include "lancer/world.hpp"
#include "support/configurations.hpp"
#include "support/ray_sets.hpp"

namespace lancer {
namespace {

// A closed sphere beside a knot, both indexed meshes, and a few spheres that stay where they are.
Scene moving_scene() {
    Scene scene;
    scene.meshes.push_back(make_icosphere(3, {0, 0, 0}, 1.0f));
    TriangleMesh knot = make_torus_knot(300, 10);
    for (Vec3f& position : knot.positions)
        position += Vec3f(2.5f, 0.0f, 0.0f);
    scene.meshes.push_back(std::move(knot));
    scene.spheres.push_back({{0.0f, 2.0f, 0.0f}, 0.4f, 0});
    scene.spheres.push_back({{2.5f, -2.0f, 0.5f}, 0.3f, 0});
    scene.materials.emplace_back();
    return scene;
}

// A wave large enough to reorder the triangles' boxes: a third of the scene's largest extent.
SineWave strong_wave(const Scene& scene) {
    return {scene.bounds(), 4, 0.3f};
}

std::vector<testing::RaySet> ray_sets(const World& world) {
    const Geometry geometry = world.geometry().view();
    const Box3f bounds = geometry.bounds();
    constexpr std::size_t share = testing::kSanitizedShare;
    return {testing::random_rays(bounds, 3000 / share, 11),
            testing::vertex_and_edge_rays(geometry.triangles, 3000 / share, 12),
            testing::axis_parallel_rays(bounds, 1000 / share, 13),
            testing::clipped_rays(bounds, 1000 / share, 14), testing::hostile_rays(bounds)};
}

// Brute force's answers on the world's present geometry, built afresh: computed once per frame, ray set and
// triangle test, and shared by every structure (the scene, the wave and the rays are the same for all).
const std::vector<Hit>& oracle_hits(const World& world, int frame, std::size_t set_index,
                                    const testing::RaySet& set, TriangleTest test) {
    static testing::BruteForceCache cache;  // the frame stands for the scene: the mesh as moved at that frame
    return cache.hits(static_cast<std::size_t>(frame), set_index, test, world.geometry().view(), set.rays);
}

// The structure against brute force on the world's present geometry: closest hits, packets and occlusion.
void expect_agreement(const World& world, TriangleTest test, int frame, const std::string& context) {
    const std::vector<testing::RaySet> sets = ray_sets(world);
    for (std::size_t s = 0; s < sets.size(); ++s) {
        const testing::RaySet& set = sets[s];
        const std::vector<Hit>& expected = oracle_hits(world, frame, s, set, test);
        std::vector<Hit> hits(set.rays.size());
        world.accel().intersect(set.rays, hits);
        const Agreement closest = compare_hits(set.rays, expected, hits);
        EXPECT_EQ(closest.mismatches, 0u) << context << ", " << set.name << ": " << closest.summary();
        const Agreement packets =
            compare_hits(set.rays, expected, testing::intersect_in_packets(world.accel(), set.rays));
        EXPECT_EQ(packets.mismatches, 0u)
            << context << " in packets, " << set.name << ": " << packets.summary();
        std::vector<std::uint8_t> occluded(set.rays.size());
        world.accel().occluded(set.rays, occluded);
        const Agreement any = compare_occlusion(set.rays, expected, occluded);
        EXPECT_EQ(any.mismatches, 0u) << context << " occlusion, " << set.name << ": " << any.summary();
    }
}

// Rays from inside the closed sphere (mesh 0) aimed at each of its vertices and edge midpoints: with the
// watertight test every one must hit, however the sphere moved.
std::size_t leaks_from_inside(const World& world) {
    const TriangleMesh& sphere = world.scene().meshes[0];
    Vec3f inside(0.0f);
    for (const Vec3f& position : sphere.positions)
        inside += position;
    inside = inside / static_cast<float>(sphere.positions.size());
    std::vector<Ray> rays;
    for (std::size_t i = 0; i < sphere.triangle_count(); ++i) {
        const Triangle triangle = sphere.triangle(i);
        for (const Vec3f target : {triangle.v0, 0.5f * (triangle.v0 + triangle.v1)})
            rays.push_back({inside, target - inside, 0.0f, kInfinity});
    }
    std::vector<Hit> hits(rays.size());
    world.accel().intersect(rays, hits);
    std::size_t leaks = 0;
    for (const Hit& hit : hits)
        leaks += hit.hit() ? 0 : 1;
    return leaks;
}

// Every hit field as bits, so that equal answers are equal bit for bit.
void expect_same_bits(const std::vector<Hit>& expected, const std::vector<Hit>& actual,
                      const std::string& context) {
    ASSERT_EQ(expected.size(), actual.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < expected.size(); ++i) {
        differ +=
            expected[i].prim != actual[i].prim ||
                    std::bit_cast<std::uint32_t>(expected[i].t) !=
                        std::bit_cast<std::uint32_t>(actual[i].t) ||
                    std::bit_cast<std::uint32_t>(expected[i].u) !=
                        std::bit_cast<std::uint32_t>(actual[i].u) ||
                    std::bit_cast<std::uint32_t>(expected[i].v) != std::bit_cast<std::uint32_t>(actual[i].v)
                ? 1
                : 0;
    }
    EXPECT_EQ(differ, 0u) << context << ": " << differ << " of " << expected.size() << " rays differ";
}

std::vector<MeshVertices> moves_of(const std::vector<std::vector<Vec3f>>& positions) {
    std::vector<MeshVertices> moves;
    for (std::size_t mesh = 0; mesh < positions.size(); ++mesh)
        moves.push_back({mesh, positions[mesh]});
    return moves;
}

class UpdateTest : public ::testing::TestWithParam<testing::Configuration> {};

TEST_P(UpdateTest, AgreesWithBruteForceAfterEveryUpdate) {
    for (TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        const Scene rest = moving_scene();
        const SineWave wave = strong_wave(rest);
        World world(rest, GetParam().name, GetParam().options(test));
        for (int frame = 1; frame <= 3; ++frame) {
            const std::vector<std::vector<Vec3f>> moved = deformed_meshes(rest, wave, frame);
            const UpdateReport report = world.update_vertices(moves_of(moved));
            const std::string context = GetParam().label() + ", frame " + std::to_string(frame) +
                                        (test == TriangleTest::Watertight ? ", watertight" : ", moller");
            EXPECT_EQ(world.scene().meshes[1].positions, moved[1]) << context;
            if (report.method == UpdateMethod::Refit) {
                EXPECT_EQ(world.accel().update_method(), UpdateMethod::Refit) << context;
                EXPECT_GT(report.sah_ratio, 0.0) << context;
            }
            expect_agreement(world, test, frame, context);
            if (test == TriangleTest::Watertight) {
                EXPECT_EQ(leaks_from_inside(world), 0u) << context << ": rays escaped the moved sphere";
            }
        }
    }
}

TEST_P(UpdateTest, RefittingToTheRestPoseGivesTheFirstAnswersBitForBit) {
    const Scene rest = moving_scene();
    // No rebuild on the way: a tree rebuilt on a moved mesh is another tree, whose ties may fall otherwise.
    BuildOptions options = GetParam().options(TriangleTest::Watertight);
    options.group<BvhOptions>().refit_threshold = 1e9;
    World world(rest, GetParam().name, options);
    const testing::RaySet set = testing::random_rays(world.geometry().view().bounds(), 4000, 21);
    std::vector<Hit> before(set.rays.size()), after(set.rays.size());
    world.accel().intersect(set.rays, before);
    for (int frame = 1; frame <= 2; ++frame)
        world.update_vertices(moves_of(deformed_meshes(rest, strong_wave(rest), frame)));
    std::vector<std::vector<Vec3f>> rest_positions;
    for (const TriangleMesh& mesh : rest.meshes)
        rest_positions.push_back(mesh.positions);
    const UpdateReport report = world.update_vertices(moves_of(rest_positions));
    world.accel().intersect(set.rays, after);
    expect_same_bits(before, after, GetParam().label());
    EXPECT_NEAR(report.sah_ratio, 1.0, 1e-12) << GetParam().label();
    // The structures that watch their SAH cost (the BVHs) report the same ratio among their figures.
    const AccelStats stats = world.accel().stats();
    if (const AccelFigure* ratio = stats.find("sah_ratio")) {
        EXPECT_EQ(ratio->value, report.sah_ratio);
    }
}

// Every structure, the ones built on the binary BVH with spatial splits too (which rebuild), and Embree with
// its refit quality, held to brute force like the others here since it is traced on the same moved mesh.
std::vector<testing::Configuration> structures_under_test() {
    std::vector<std::string_view> names = accel_names();
    std::erase(names, std::string_view("brute"));
    std::erase_if(names, [](std::string_view name) { return name.starts_with("embree"); });
    return testing::agreement_configurations(names);
}

INSTANTIATE_TEST_SUITE_P(Structures, UpdateTest, ::testing::ValuesIn(structures_under_test()),
                         [](const auto& param_info) { return param_info.param.label(); });
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(UpdateTest);

TEST(Update, TheBvhsRefitAndTheOthersRebuild) {
    for (const std::string_view name : accel_names()) {
        if (name.starts_with("embree")) continue;
        const std::unique_ptr<Accel> accel = make_accel(name);
        const bool refits = testing::built_on_the_binary_bvh(name);
        EXPECT_EQ(accel->update_method(), refits ? UpdateMethod::Refit : UpdateMethod::Rebuild) << name;
    }
    BuildOptions spatial;
    spatial.group<BvhOptions>().spatial_splits = true;
    const Scene scene = moving_scene();
    EXPECT_EQ(World(scene, "bvh8", spatial).accel().update_method(), UpdateMethod::Rebuild);
}

BuildOptions with_refit_threshold(double threshold) {
    BuildOptions options;
    options.group<BvhOptions>().refit_threshold = threshold;
    return options;
}

// `rest` with its meshes moved to `positions`.
Scene posed(const Scene& rest, const std::vector<std::vector<Vec3f>>& positions) {
    Scene scene = rest;
    for (std::size_t mesh = 0; mesh < positions.size(); ++mesh)
        scene.meshes[mesh].positions = positions[mesh];
    return scene;
}

TEST(Update, TheSahWatchRebuildsPastItsThreshold) {
    const Scene rest = moving_scene();
    const std::vector<std::vector<Vec3f>> moved = deformed_meshes(rest, strong_wave(rest), 1);
    for (const std::string_view name : {"bvh", "bvh8"}) {
        World refitted(rest, name, with_refit_threshold(1e9));
        const UpdateReport refit = refitted.update_vertices(moves_of(moved));
        EXPECT_EQ(refit.method, UpdateMethod::Refit) << name;
        // The wave stretches the boxes of the triangles it tilts: the refitted tree costs more.
        EXPECT_GT(refit.sah_ratio, 1.0) << name;
        EXPECT_EQ(refitted.accel().stats().value("sah_ratio"), refit.sah_ratio) << name;

        World rebuilt(rest, name, with_refit_threshold(1.0));
        const UpdateReport rebuild = rebuilt.update_vertices(moves_of(moved));
        EXPECT_EQ(rebuild.method, UpdateMethod::Rebuild) << name;
        EXPECT_EQ(rebuild.sah_ratio, 1.0) << name;
        EXPECT_EQ(rebuilt.accel().stats().value("sah_ratio"), 1.0) << name;
        // A rebuilt tree costs what a fresh build on the moved mesh costs.
        EXPECT_EQ(
            rebuilt.accel().stats().value("sah_cost"),
            World(posed(rest, moved), name, with_refit_threshold(1.0)).accel().stats().value("sah_cost"));
    }
}

template <class T, class Allocator>
std::vector<unsigned char> bytes_of(const std::vector<T, Allocator>& array) {
    const auto* first = reinterpret_cast<const unsigned char*>(array.data());
    return {first, first + array.size() * sizeof(T)};
}

// How many headers of block boxes bvh8 has (bvh.leaf_boxes), each checked to hold every primitive of its
// blocks in `geometry`.
std::size_t checked_leaf_boxes(const Bvh8Accel& bvh8, const Geometry& geometry) {
    std::size_t headers = 0;
    for (const WideBvhNode<8>& node : bvh8.nodes()) {
        for (int slot = 0; slot < 8; ++slot) {
            if (node.prim_count[slot] == 0 || !has_leaf_boxes(node.child[slot])) continue;
            ++headers;
            const Bvh8Accel::Block& header = bvh8.blocks()[leaf_start(node.child[slot])];
            const LeafSpan span = leaf_span<8>(node.child[slot], node.prim_count[slot]);
            for (std::uint32_t b = span.first; b < span.end; ++b) {
                const auto lane = static_cast<int>(b - span.first);
                const Box3f box{
                    {header.vertex[0][0][lane], header.vertex[0][1][lane], header.vertex[0][2][lane]},
                    {header.vertex[1][0][lane], header.vertex[1][1][lane], header.vertex[1][2][lane]}};
                for (const std::uint32_t prim : bvh8.blocks()[b].prim) {
                    if (prim == Bvh8Accel::Block::kNoPrimitive) continue;
                    EXPECT_TRUE(box.contains(primitive_bounds(geometry, prim))) << "primitive " << prim;
                }
            }
        }
    }
    return headers;
}

TEST(Update, RefitToTheBuiltPositionsGivesTheBuiltTreeByteForByte) {
    const Scene rest = moving_scene();
    const Scene moved = posed(rest, deformed_meshes(rest, strong_wave(rest), 1));
    const SceneGeometry rest_geometry(rest), moved_geometry(moved);
    const BuildOptions never = with_refit_threshold(1e9);

    BvhAccel bvh;
    bvh.build(rest_geometry.view(), never);
    const std::vector<unsigned char> nodes = bytes_of(bvh.nodes());
    EXPECT_EQ(bvh.update(moved_geometry.view()).method, UpdateMethod::Refit);
    EXPECT_NE(bytes_of(bvh.nodes()), nodes) << "the refit left the moved mesh's boxes as they were";
    bvh.update(rest_geometry.view());
    EXPECT_EQ(bytes_of(bvh.nodes()), nodes);

    // With and without the headers of block boxes (bvh.leaf_boxes), which the refit rewrites too.
    for (const LeafBoxes boxes : {LeafBoxes::Off, LeafBoxes::On}) {
        BuildOptions options = never;
        options.group<BvhOptions>().leaf_boxes = boxes;
        Bvh8Accel bvh8;
        bvh8.build(rest_geometry.view(), options);
        const std::vector<unsigned char> wide_nodes = bytes_of(bvh8.nodes()),
                                         blocks = bytes_of(bvh8.blocks());
        EXPECT_EQ(bvh8.update(moved_geometry.view()).method, UpdateMethod::Refit);
        EXPECT_NE(bytes_of(bvh8.blocks()), blocks) << "the refit left the moved triangles as they were";
        const std::size_t headers = checked_leaf_boxes(bvh8, moved_geometry.view());
        EXPECT_EQ(headers > 0, boxes == LeafBoxes::On);
        bvh8.update(rest_geometry.view());
        EXPECT_EQ(bytes_of(bvh8.nodes()), wide_nodes);
        EXPECT_EQ(bytes_of(bvh8.blocks()), blocks);
    }
}

TEST(Update, BadInputLeavesTheWorldAsItWas) {
    const Scene rest = moving_scene();
    World world(rest, "bvh8", BuildOptions{});
    const testing::RaySet set = testing::random_rays(world.geometry().view().bounds(), 2000, 31);
    std::vector<Hit> before(set.rays.size()), after(set.rays.size());
    world.accel().intersect(set.rays, before);

    std::vector<Vec3f> positions = rest.meshes[1].positions;
    auto expect_refused = [&](std::span<const MeshVertices> moves, const std::string& message) {
        try {
            world.update_vertices(moves);
            ADD_FAILURE() << "accepted: " << message;
        } catch (const std::invalid_argument& error) {
            EXPECT_NE(std::string(error.what()).find(message), std::string::npos) << error.what();
        }
        EXPECT_EQ(world.scene().meshes[1].positions, rest.meshes[1].positions) << message;
        world.accel().intersect(set.rays, after);
        expect_same_bits(before, after, message);
    };
    const std::vector<Vec3f> short_positions(positions.begin(), positions.end() - 1);
    expect_refused(std::vector<MeshVertices>{{1, short_positions}}, "which has");
    for (const float bad : {std::numeric_limits<float>::quiet_NaN(), kInfinity, 0x1p61f}) {
        positions[7].y = bad;
        expect_refused(std::vector<MeshVertices>{{0, rest.meshes[0].positions}, {1, positions}},
                       "vertex 7 of mesh 1");
    }
    positions = rest.meshes[1].positions;
    expect_refused(std::vector<MeshVertices>{{2, positions}}, "mesh 2, the scene has 2");
    expect_refused(std::vector<MeshVertices>{{1, positions}, {1, positions}}, "named twice");
}

// The box an update hands the structure is the box of the moved triangles and spheres: taken from the
// positions where every vertex is a corner (the sphere), from the triangles where one is not (the knot, whose
// stray vertex is moved far away and must not widen it).
TEST(Update, TheBoxFollowsTheTrianglesAndNotAStrayVertex) {
    Scene rest = moving_scene();
    rest.meshes[1].positions.push_back({50.0f, 50.0f, 50.0f});  // no triangle's corner
    World world(rest, "bvh8", BuildOptions{});
    const SineWave wave = strong_wave(rest);
    for (int frame = 1; frame <= 2; ++frame) {
        std::vector<std::vector<Vec3f>> moved = deformed_meshes(rest, wave, frame);
        moved[1].back() = {-60.0f, 70.0f, 80.0f * static_cast<float>(frame)};
        world.update_vertices(moves_of(moved));
        Box3f expected;
        for (const Triangle& triangle : world.geometry().view().triangles)
            expected.extend(triangle.bounds());
        for (const Sphere& sphere : rest.spheres)
            expected.extend(sphere.bounds());
        EXPECT_EQ(world.geometry().hit_bounds().lo, expected.lo) << "frame " << frame;
        EXPECT_EQ(world.geometry().hit_bounds().hi, expected.hi) << "frame " << frame;
        EXPECT_EQ(world.accel().bounds().lo, expected.lo) << "frame " << frame;
        EXPECT_EQ(world.accel().bounds().hi, expected.hi) << "frame " << frame;
        EXPECT_LT(expected.hi.x, 10.0f) << "frame " << frame;
    }
}

// Spheres are primitives too: moved between updates (same count), every structure follows them; and an empty
// geometry updates to itself.
TEST(Update, MovedSpheresAndEmptyGeometryAreFollowed) {
    std::vector<Sphere> spheres = {{{0, 0, 0}, 0.5f, 0}, {{2, 0, 0}, 0.25f, 0}, {{0, 2, 1}, 0.0f, 0}};
    const testing::RaySet set = testing::random_rays({{-2, -2, -2}, {4, 4, 4}}, 2000, 51);
    for (const std::string_view name : accel_names()) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build({{}, spheres}, BuildOptions{});
        std::vector<Sphere> moved = spheres;
        moved[0].center = {1.0f, 1.0f, 0.5f};
        moved[1].radius = 0.75f;
        accel->update({{}, moved});
        BruteAccel brute;
        brute.build({{}, moved}, BuildOptions{});
        std::vector<Hit> expected(set.rays.size()), hits(set.rays.size());
        brute.intersect(set.rays, expected);
        accel->intersect(set.rays, hits);
        const Agreement agreement = compare_hits(set.rays, expected, hits);
        // Embree has its own sphere test: its t within its rounding is all compare_hits asks.
        EXPECT_EQ(agreement.mismatches, 0u) << name << ": " << agreement.summary();
        EXPECT_GT(agreement.hits, 100u) << name;

        const std::unique_ptr<Accel> empty = make_accel(name);
        empty->build({}, BuildOptions{});
        EXPECT_NO_THROW(empty->update({})) << name;
        std::vector<Hit> none(set.rays.size());
        empty->intersect(set.rays, none);
        EXPECT_TRUE(std::none_of(none.begin(), none.end(), [](const Hit& hit) { return hit.hit(); })) << name;
    }
}

TEST(Update, AccelRefusesOtherCountsAndCoordinatesOutsideTheDomain) {
    const Scene scene = moving_scene();
    const SceneGeometry geometry(scene);
    for (const std::string_view name : {"bvh", "bvh8_packet", "grid", "plucker"}) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(geometry.view(), BuildOptions{});
        const Geometry fewer{geometry.view().triangles.first(10), geometry.view().spheres};
        EXPECT_THROW(accel->update(fewer), std::invalid_argument) << name;
        std::vector<Triangle> far(geometry.view().triangles.begin(), geometry.view().triangles.end());
        far[3].v1.z = std::numeric_limits<float>::quiet_NaN();
        EXPECT_THROW(accel->update({far, geometry.view().spheres}), std::invalid_argument) << name;
        // Still the structure it was: its answers on the geometry it was built on.
        BruteAccel brute;
        brute.build(geometry.view(), BuildOptions{});
        const testing::RaySet set = testing::random_rays(geometry.view().bounds(), 2000, 41);
        std::vector<Hit> expected(set.rays.size()), hits(set.rays.size());
        brute.intersect(set.rays, expected);
        accel->intersect(set.rays, hits);
        EXPECT_EQ(compare_hits(set.rays, expected, hits).mismatches, 0u) << name;
    }
}

TEST(SineWave, IsTheDocumentedWave) {
    const Box3f box{{0, 0, 0}, {4, 2, 1}};
    const SineWave wave{box, 8, 0.05f};
    const std::vector<Vec3f> rest = {{0, 1, 0}, {1, 1, 0.5f}, {3, 0, 1}};
    std::vector<Vec3f> out(rest.size()), again(rest.size());
    const double lift = 0.05 * 4.0;
    for (int frame = 0; frame < 8; ++frame) {
        wave.apply(rest, frame, out);
        for (std::size_t i = 0; i < rest.size(); ++i) {
            const double expected =
                rest[i].y + lift * std::sin(2.0 * std::numbers::pi * (rest[i].x / 4.0 - frame / 8.0));
            EXPECT_NEAR(out[i].y, expected, 1e-6) << frame << " " << i;
            EXPECT_EQ(out[i].x, rest[i].x);
            EXPECT_EQ(out[i].z, rest[i].z);
        }
    }
    // One period later the same frame, bit for bit.
    wave.apply(rest, 3, out);
    wave.apply(rest, 11, again);
    EXPECT_EQ(out, again);
    EXPECT_THROW(wave.apply(rest, 0, std::span(out).first(2)), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
