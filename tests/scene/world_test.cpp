// lancer::World: the scene, its geometry and one structure made together, and a `.plo` file as another way
// to make one (save_structure, load_structure).
#include "lancer/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "lancer/agreement.hpp"
#include "lancer/generate.hpp"
#include "support/ray_sets.hpp"

namespace lancer {
namespace {

// An icosphere and a torus knot with two spheres: meshes, spheres and more than one material.
Scene test_scene() {
    Scene scene;
    scene.meshes.push_back(make_icosphere(2, {-1.5f, 0.0f, 0.0f}, 1.0f));
    TriangleMesh knot = make_torus_knot(64, 8);
    knot.material = 1;
    scene.meshes.push_back(std::move(knot));
    scene.spheres.push_back({{2.0f, 1.0f, 0.5f}, 0.5f, 1});
    scene.spheres.push_back({{0.0f, -2.0f, 0.0f}, 0.25f, 0});
    scene.materials.resize(2);
    scene.materials[1].color = {0.2f, 0.7f, 0.3f};
    return scene;
}

std::vector<Ray> test_rays(const World& world) {
    return testing::random_rays(world.scene().bounds(), 4000, 23).rays;
}

std::vector<Hit> trace(const World& world, const std::vector<Ray>& rays) {
    std::vector<Hit> hits(rays.size());
    world.accel().intersect(rays, hits);
    return hits;
}

void expect_same_hits(const std::vector<Hit>& expected, const std::vector<Hit>& actual) {
    ASSERT_EQ(expected.size(), actual.size());
    EXPECT_EQ(std::memcmp(expected.data(), actual.data(), expected.size() * sizeof(Hit)), 0);
}

class WorldTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = std::filesystem::temp_directory_path() /
               ("lancer_world_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }

    std::filesystem::path dir_;
};

TEST_F(WorldTest, BuildsTheNamedStructureOverItsScene) {
    const Scene scene = test_scene();
    const World world(scene, "bvh", build_options(TriangleTest::Watertight));
    EXPECT_EQ(world.accel().name(), "bvh");
    EXPECT_EQ(world.options().triangle_test, TriangleTest::Watertight);
    EXPECT_EQ(world.scene().meshes.size(), 2u);
    EXPECT_EQ(world.geometry().view().size(), scene.triangle_count() + scene.spheres.size());
    const World brute(scene, "brute", build_options(TriangleTest::Watertight));
    const std::vector<Ray> rays = test_rays(world);
    const std::vector<Hit> hits = trace(world, rays);
    const Agreement agreement = compare_hits(rays, trace(brute, rays), hits);
    EXPECT_EQ(agreement.mismatches, 0u) << agreement.summary();
    EXPECT_GT(agreement.hits, rays.size() / 20);
}

TEST_F(WorldTest, MovesWithoutMovingWhatItsStructureReads) {
    World world(test_scene(), "bvh8", build_options(TriangleTest::MollerTrumbore));
    const std::vector<Ray> rays = test_rays(world);
    const std::vector<Hit> before = trace(world, rays);
    const World moved = std::move(world);
    expect_same_hits(before, trace(moved, rays));
}

TEST_F(WorldTest, RefusesAnUnknownStructure) {
    EXPECT_THROW(World(test_scene(), "no_such_structure", {}), std::invalid_argument);
}

// The scene moved in is taken only by a build that succeeds, and take_scene() gives back what the world
// held, its updates included: what a Python scene relies on to keep one copy of its meshes.
TEST_F(WorldTest, AFailedBuildLeavesTheSceneMovedInAndTakeSceneGivesItBack) {
    Scene outside = test_scene();
    outside.meshes[0].positions[3] = Vec3f(0x1p61f, 0.0f, 0.0f);  // beyond the contract's domain
    const Scene expected = outside;
    EXPECT_THROW(World(std::move(outside), "bvh8", {}), std::invalid_argument);
    ASSERT_EQ(outside.meshes.size(), expected.meshes.size());
    EXPECT_EQ(outside.meshes[0].positions, expected.meshes[0].positions);
    EXPECT_EQ(outside.meshes[1].indices, expected.meshes[1].indices);
    EXPECT_EQ(outside.spheres.size(), expected.spheres.size());

    World world(test_scene(), "bvh8", {});
    std::vector<Vec3f> moved = world.scene().meshes[1].positions;
    for (Vec3f& p : moved)
        p += Vec3f(0.25f, 0.0f, 0.0f);
    world.update_vertices(1, moved);
    const Scene taken = std::move(world).take_scene();
    EXPECT_EQ(taken.meshes[1].positions, moved);
    EXPECT_EQ(taken.meshes[0].positions, test_scene().meshes[0].positions);
    EXPECT_EQ(taken.materials.size(), 2u);
}

TEST(TriangleMeshTest, ReserveMakesRoomForTheCountsGiven) {
    TriangleMesh mesh;
    mesh.reserve(1000, 3000);
    EXPECT_GE(mesh.positions.capacity(), 1000u);
    EXPECT_GE(mesh.indices.capacity(), 9000u);
    EXPECT_TRUE(mesh.positions.empty());
    EXPECT_TRUE(mesh.indices.empty());
}

TEST_F(WorldTest, SavedStructureLoadsBackWithTheSameAnswers) {
    BuildOptions options = build_options(TriangleTest::Watertight);
    set_build_option(options, "plucker.balanced=false");  // a variant the loaded world must report
    const World world(test_scene(), "plucker", options);
    const std::filesystem::path file = dir_ / "world.plo";
    world.save_structure(file);
    const World loaded = World::load_structure(file);
    EXPECT_EQ(loaded.accel().name(), "plucker");
    EXPECT_EQ(loaded.options().triangle_test, TriangleTest::Watertight);
    EXPECT_EQ(build_option_value(loaded.options(), "plucker.balanced"), "false");
    EXPECT_EQ(build_option_value(loaded.options(), "plucker.stored_boxes"), "true");
    EXPECT_EQ(loaded.geometry().view().size(), world.geometry().view().size());
    ASSERT_EQ(loaded.scene().meshes.size(), 1u);  // the file's triangles as one mesh, in their order
    EXPECT_EQ(loaded.scene().meshes[0].triangle_count(), world.scene().triangle_count());
    EXPECT_EQ(loaded.scene().spheres.size(), 2u);
    const std::vector<Ray> rays = test_rays(world);
    expect_same_hits(trace(world, rays), trace(loaded, rays));
    // The triangle test can be replaced at load time.
    EXPECT_EQ(World::load_structure(file, TriangleTest::MollerTrumbore).options().triangle_test,
              TriangleTest::MollerTrumbore);
}

// A scene at the coordinate domain's edge, which the structure sees scaled into the ordinary range
// (docs/numerical-contract.md, "Coordinate domain"): its file holds the caller's geometry and the octree of
// the scaled one, and loads back with the same answers.
TEST_F(WorldTest, ASceneAtTheDomainsEdgeLoadsBackWithTheSameAnswers) {
    Scene scene = test_scene();
    const auto scaled = [](Vec3f p) {
        return Vec3f(std::ldexp(p.x, 58), std::ldexp(p.y, 58), std::ldexp(p.z, 58));
    };
    for (TriangleMesh& mesh : scene.meshes) {
        for (Vec3f& position : mesh.positions)
            position = scaled(position);
    }
    for (Sphere& sphere : scene.spheres)
        sphere.center = scaled(sphere.center), sphere.radius = std::ldexp(sphere.radius, 58);
    const World world(scene, "plucker", build_options(TriangleTest::Watertight));
    const std::filesystem::path file = dir_ / "huge.plo";
    world.save_structure(file);
    const World loaded = World::load_structure(file);
    const std::vector<Ray> rays = test_rays(world);
    const std::vector<Hit> hits = trace(world, rays);
    expect_same_hits(hits, trace(loaded, rays));
    const World brute(scene, "brute", build_options(TriangleTest::Watertight));
    const Agreement agreement = compare_hits(rays, trace(brute, rays), hits);
    EXPECT_EQ(agreement.mismatches, 0u) << agreement.summary();
    EXPECT_GT(agreement.hits, rays.size() / 20);
}

// The packet walk traces the plucker structure's arrays as they are, so it saves them too.
TEST_F(WorldTest, APluckerPacketWorldSavesItsOctree) {
    const World world(test_scene(), "plucker_packet", build_options(TriangleTest::Watertight));
    const std::filesystem::path file = dir_ / "packet.plo";
    world.save_structure(file);
    const World loaded = World::load_structure(file);
    EXPECT_EQ(loaded.accel().name(), "plucker");
    const std::vector<Ray> rays = test_rays(world);
    expect_same_hits(trace(world, rays), trace(loaded, rays));
}

TEST_F(WorldTest, OnlyThePluckerStructuresAreSaved) {
    for (const std::string_view name : {"bvh", "bvh_packet", "bvh8", "grid"}) {
        const World world(test_scene(), name, {});
        const std::filesystem::path file = dir_ / (std::string(name) + ".plo");
        try {
            world.save_structure(file);
            ADD_FAILURE() << name << " was saved";
        } catch (const StructureFileError& error) {
            EXPECT_NE(std::string(error.what()).find("only the plucker structures"), std::string::npos)
                << error.what();
        }
        EXPECT_FALSE(std::filesystem::exists(file)) << name;
    }
}

TEST_F(WorldTest, ADamagedFileIsAStructureFileError) {
    const std::filesystem::path file = dir_ / "damaged.plo";
    std::ofstream(file, std::ios::binary) << "LANCERPO and then nothing that a header needs";
    EXPECT_THROW(static_cast<void>(World::load_structure(file)), StructureFileError);
    EXPECT_THROW(static_cast<void>(World::load_structure(dir_ / "absent.plo")), StructureFileError);
}

}  // namespace
}  // namespace lancer
