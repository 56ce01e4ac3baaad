// Plücker octree files (src/accel/plucker/serialise.hpp): a written and read structure answers every ray
// exactly as the one built, for every layout variant; damaged files are refused with a message naming the
// problem, before any allocation the file's size does not justify.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "accel/plucker/plucker.hpp"
#include "accel/plucker/serialise.hpp"
#include "lancer/generate.hpp"
#include "support/allocation_probe.hpp"
#include "support/ray_sets.hpp"

namespace lancer::plucker {
namespace {

namespace fs = std::filesystem;

struct Fixture {
    std::vector<Triangle> triangles;
    std::vector<Sphere> spheres;

    Fixture() {
        make_icosphere(3, {0.1f, 0.2f, -0.3f}, 1.0f).append_triangles(triangles);
        make_torus_knot(120, 6).append_triangles(triangles);
        spheres = {{{1.5f, 1.5f, 0.0f}, 0.3f, 0}, {{-1.2f, 0.5f, 1.0f}, 0.2f, 0}};
    }
    [[nodiscard]] Geometry geometry() const { return {triangles, spheres}; }
};

class PluckerFileTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("lancer_plucker_" +
                std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    [[nodiscard]] fs::path built_file(const PluckerAccel& accel,
                                      const std::string& name = "scene.plo") const {
        const fs::path file = dir_ / name;
        write_plucker_file(file, fixture_.geometry(), accel.layout(), TriangleTest::Watertight);
        return file;
    }
    [[nodiscard]] std::vector<char> bytes(const fs::path& file) const {
        std::ifstream in(file, std::ios::binary);
        return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    }
    [[nodiscard]] fs::path write_bytes(const std::vector<char>& data, const std::string& name) const {
        const fs::path file = dir_ / name;
        std::ofstream(file, std::ios::binary).write(data.data(), static_cast<std::streamsize>(data.size()));
        return file;
    }
    // The message of the PluckerFileError reading `file` throws ("" when it reads).
    [[nodiscard]] static std::string refusal(const fs::path& file) {
        try {
            [[maybe_unused]] const PluckerFile read = read_plucker_file(file);
        } catch (const PluckerFileError& error) {
            return error.what();
        }
        return "";
    }

    Fixture fixture_;
    fs::path dir_;
};

TEST_F(PluckerFileTest, RoundTripGivesTheSameHitsForEveryLayout) {
    const Box3f bounds = fixture_.geometry().bounds();
    std::vector<Ray> rays = testing::random_rays(bounds, 3000, 5).rays;
    for (const auto& extra : {testing::axis_parallel_rays(bounds, 1000, 6), testing::hostile_rays(bounds)})
        rays.insert(rays.end(), extra.rays.begin(), extra.rays.end());
    for (int variant = 0; variant < 8; ++variant) {
        BuildOptions options = build_options(TriangleTest::Watertight);
        options.group<PluckerOptions>().max_depth = 7;
        options.group<PluckerOptions>().leaf_size = 3;
        options.group<PluckerOptions>().stored_boxes = variant & 1;
        options.group<PluckerOptions>().balanced = variant & 2;
        options.group<PluckerOptions>().morton = variant & 4;
        PluckerAccel built;
        built.build(fixture_.geometry(), options);
        const PluckerFile read = read_plucker_file(built_file(built));
        EXPECT_EQ(read.triangle_test, TriangleTest::Watertight);
        ASSERT_EQ(read.triangles.size(), fixture_.triangles.size());
        ASSERT_EQ(read.spheres.size(), fixture_.spheres.size());
        EXPECT_EQ(read.layout.cells, built.layout().cells);
        EXPECT_EQ(read.layout.locate, built.layout().locate);
        EXPECT_EQ(read.layout.cube_map.texels, built.layout().cube_map.texels);
        PluckerAccel loaded;
        loaded.adopt({read.triangles, read.spheres}, build_options(read.triangle_test), read.layout);
        EXPECT_EQ(loaded.stats().count("leaves"), built.stats().count("leaves"));
        EXPECT_EQ(loaded.memory_bytes(), built.memory_bytes());
        std::vector<Hit> expected(rays.size()), hits(rays.size());
        built.intersect(rays, expected);
        loaded.intersect(rays, hits);
        for (std::size_t i = 0; i < rays.size(); ++i) {
            ASSERT_EQ(hits[i].prim, expected[i].prim) << "variant " << variant << " ray " << i;
            ASSERT_EQ(hits[i].t, expected[i].t);
        }
    }
}

TEST_F(PluckerFileTest, RefusesMissingEmptyTruncatedAndPaddedFiles) {
    PluckerAccel accel;
    accel.build(fixture_.geometry(), {});
    const std::vector<char> good = bytes(built_file(accel));
    EXPECT_NE(refusal(dir_ / "absent.plo").find("cannot open"), std::string::npos);
    EXPECT_NE(refusal(write_bytes({}, "empty.plo")).find("wrong magic"), std::string::npos);
    for (const std::size_t size :
         {std::size_t{100}, sizeof(PluckerFileHeader), good.size() / 2, good.size() - 1}) {
        const std::vector<char> cut(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(size));
        EXPECT_NE(refusal(write_bytes(cut, "cut.plo")).find("truncated"), std::string::npos) << size;
    }
    std::vector<char> padded = good;
    padded.push_back(0);
    EXPECT_NE(refusal(write_bytes(padded, "padded.plo")).find("padded"), std::string::npos);
}

TEST_F(PluckerFileTest, RefusesWrongMagicVersionAndLayout) {
    PluckerAccel accel;
    accel.build(fixture_.geometry(), {});
    const std::vector<char> good = bytes(built_file(accel));
    std::vector<char> wrong = good;
    std::memcpy(wrong.data(), "PLYFORMA", 8);
    EXPECT_NE(refusal(write_bytes(wrong, "magic.plo")).find("wrong magic"), std::string::npos);
    wrong = good;
    wrong[offsetof(PluckerFileHeader, version)] = 1;
    EXPECT_NE(refusal(write_bytes(wrong, "version.plo")).find("version 1"), std::string::npos);
    wrong = good;
    wrong[offsetof(PluckerFileHeader, flags)] = 8;
    EXPECT_NE(refusal(write_bytes(wrong, "flags.plo")).find("flags"), std::string::npos);
    wrong = good;
    wrong[offsetof(PluckerFileHeader, cube_map_level)] = 30;
    EXPECT_NE(refusal(write_bytes(wrong, "level.plo")).find("cube map"), std::string::npos);
}

// Counts of 2^40 elements in a small file: refused from the sizes alone, nothing large allocated.
TEST_F(PluckerFileTest, HugeCountsAreRefusedBeforeAnyAllocation) {
    PluckerAccel accel;
    accel.build(fixture_.geometry(), {});
    const std::vector<char> good = bytes(built_file(accel));
    for (const std::size_t field :
         {offsetof(PluckerFileHeader, triangles), offsetof(PluckerFileHeader, cells),
          offsetof(PluckerFileHeader, primitives), offsetof(PluckerFileHeader, locate)}) {
        std::vector<char> huge = good;
        const std::uint64_t count = std::uint64_t{1} << 40;
        std::memcpy(huge.data() + field, &count, sizeof(count));
        const fs::path file = write_bytes(huge, "huge.plo");
        test::reset_largest_allocation();
        EXPECT_NE(refusal(file).find("truncated"), std::string::npos) << field;
        EXPECT_LT(test::largest_allocation(), std::size_t{1} << 16) << field;
    }
}

TEST_F(PluckerFileTest, RefusesACorruptedPayloadByItsChecksum) {
    PluckerAccel accel;
    accel.build(fixture_.geometry(), {});
    std::vector<char> data = bytes(built_file(accel));
    data[data.size() / 2] ^= 0x10;
    EXPECT_NE(refusal(write_bytes(data, "flipped.plo")).find("checksum"), std::string::npos);
}

// Files with a valid checksum whose structure is wrong: written from a damaged layout, as a crafted file
// would be. Each must be refused by the structural checks.
TEST_F(PluckerFileTest, RefusesOutOfRangeAndInconsistentStructures) {
    BuildOptions options;
    options.group<PluckerOptions>().max_depth = 6;
    options.group<PluckerOptions>().leaf_size = 3;
    PluckerAccel accel;
    accel.build(fixture_.geometry(), options);
    const PluckerLayout& good = accel.layout();
    const std::uint32_t header = header_words(true);
    // The first leaf record with a neighbour.
    std::uint32_t leaf = 0;
    while (neighbour_end(good.cells[leaf + header - 1], 5) == 0)
        leaf += header + neighbour_end(good.cells[leaf + header - 1], 5);
    const std::uint32_t link = leaf + header;

    const auto refused = [&](const PluckerLayout& layout, const std::string& name) {
        const fs::path file = dir_ / name;
        write_plucker_file(file, fixture_.geometry(), layout, TriangleTest::MollerTrumbore);
        return refusal(file);
    };
    PluckerLayout bad = good;
    bad.cells[link] = static_cast<std::uint32_t>(good.cells.size()) + 1000;  // past the end
    EXPECT_NE(refused(bad, "link_out.plo").find("inconsistent"), std::string::npos);
    bad = good;
    bad.cells[link] = 0;  // a real record, but not the neighbour
    if (good.cells[link] == 0) bad.cells[link] = header;
    EXPECT_NE(refused(bad, "link_wrong.plo").find("inconsistent"), std::string::npos);
    bad = good;
    bad.cells[leaf + kTriangleOffset] = 0x7FFFFFF0u;
    EXPECT_NE(refused(bad, "triangles_out.plo").find("out of range"), std::string::npos);
    bad = good;
    bad.locate[0] = (static_cast<std::uint32_t>(good.locate.size()) << 1) | 1u;  // children past the end
    EXPECT_NE(refused(bad, "children_out.plo").find("out of range"), std::string::npos);
    bad = good;
    bad.locate[0] = 1u;  // the root its own child
    EXPECT_NE(refused(bad, "cycle.plo").find("out of range"), std::string::npos);
    bad = good;
    bad.locate.back() = (static_cast<std::uint32_t>(good.cells.size()) + 5) << 1;  // a leaf past the stream
    EXPECT_FALSE(refused(bad, "leaf_out.plo").empty());
    bad = good;
    bad.primitives[0].prim = 1u << 30;
    EXPECT_NE(refused(bad, "prim_out.plo").find("out of range"), std::string::npos);
    bad = good;
    bad.primitives[0].triangle.v0.x += 1.0f;  // a copy that is not the geometry's triangle
    EXPECT_NE(refused(bad, "copy.plo").find("inconsistent"), std::string::npos);
    bad = good;
    bad.cube_map.texels[3] ^= 4u;
    EXPECT_NE(refused(bad, "cube_map.plo").find("inconsistent"), std::string::npos);
    bad = good;
    bad.boxes[1].planes[4] += 0.5f;
    EXPECT_NE(refused(bad, "box.plo").find("inconsistent"), std::string::npos);
    bad = good;
    bad.cube.size *= 2.0f;
    EXPECT_NE(refused(bad, "cube.plo").find("root cube"), std::string::npos);
    EXPECT_EQ(refused(good, "good.plo"), "");
}

}  // namespace
}  // namespace lancer::plucker
