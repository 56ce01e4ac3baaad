// Bad input never crashes, hangs or allocates blindly: every file of the broken corpus gives a LoadError
// that names the file, the line and what was expected; garbage and every truncation of good files give a
// LoadError or a scene, nothing else.
#include <gtest/gtest.h>

#include <cctype>
#include <chrono>
#include <fstream>
#include <ostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene_test_util.hpp"
#include "support/allocation_probe.hpp"

namespace lancer {
namespace {

using test::corpus;

struct BrokenFile {
    const char* name;  // under tests/scene/data/broken/
    std::size_t line;  // 0: the error is not tied to a line
    const char* expected;
};

// Lines are those of the files as written in tests/scene/data/broken/.
const BrokenFile kBrokenFiles[] = {
    {"bad_magic.off", 1, "expected 'OFF', got 'OFFF'"},
    {"truncated_in_vertices.off", 5, "expected 3 vertex coordinates, got 2"},
    {"truncated_in_faces.off", 8, "unexpected end of file: expected 3 faces, got 2"},
    {"truncated_in_face.off", 16, "expected 4 vertex indices, got 2"},
    {"non_numeric.off", 4, "expected 3 vertex coordinates, got 'abc'"},
    {"nan_coordinate.off", 5, "expected 3 vertex coordinates, got 'nan' (not a finite number)"},
    {"trailing_garbage.off", 5, "expected 3 vertex coordinates, got '1.5x'"},
    {"index_out_of_range.off", 15, "face index 17 out of range [0, 12)"},
    {"negative_index.off", 7, "face index -1 out of range [0, 4)"},
    {"two_vertex_face.off", 7, "expected a face of at least 3 vertices, got 2"},
    {"huge_vertex_count.off", 2, "announces 1000000000000 vertices"},
    {"huge_face_count.off", 2, "announces 1000000000000 faces"},
    {"huge_polygon.off", 6, "announces 100000 face vertices"},
    {"extra_face.off", 7, "expected the end of the file after 1 faces, got '3'"},
    {"negative_count.off", 2, "expected a vertex count, got '-3' (negative)"},
    {"empty.off", 1, "unexpected end of file: expected 'OFF'"},
    {"only_comment.off", 2, "unexpected end of file: expected 'OFF'"},
    {"material_out_of_range.dsc", 7, "material index 2 out of range [0, 2)"},
    {"count_mismatch.dsc", 5, "triangle count 2 does not match the 3 faces of count_mismatch.off"},
    {"missing_off.dsc", 0, "missing_off.off"},
    {"huge_material_count.dsc", 3, "announces 1000000000000 materials"},
    {"zero_width.dsc", 2, "expected an image width between 1 and 65536, got '0'"},
    {"unknown_keyword.nff", 3, "expected a keyword (v, b, l, f, c, s, p, pp, plane or ambient), got 'x'"},
    {"polygon_two_vertices.nff", 2, "expected a polygon of at least 3 vertices, got 2"},
    {"polygon_short.nff", 5, "expected a polygon vertex x y z, got 's'"},
    {"sphere_radius_zero.nff", 2, "expected a positive sphere radius, got '0'"},
    {"truncated.nff", 4, "unexpected end of file: expected 4 polygon vertices, got 2"},
    {"truncated_view.nff", 7, "unexpected end of file: expected an image height after 'resolution'"},
    {"view_out_of_order.nff", 2, "expected 'from', got 'at'"},
    {"cone_opposite_radii.nff", 1, "expected cone radii of one sign"},
    {"huge_polygon.nff", 1, "announces 100000 polygon vertices"},
    {"empty.nff", 1, "unexpected end of file: expected a keyword"},
    {"overflowing_sphere.nff", 0, "a sphere reaches outside the coordinate domain [-2^60, 2^60]"},
    {"overflowing_cone.nff", 0,
     "mesh 'overflowing_cone' has a vertex outside the coordinate domain [-2^60, 2^60]"},
    // Finite, but beyond the contract's domain (fuzz findings 8 and 12, docs/robustness.md).
    {"vertex_beyond_domain.off", 0, "has a vertex outside the coordinate domain [-2^60, 2^60]"},
    {"sphere_beyond_domain.nff", 0, "a sphere reaches outside the coordinate domain [-2^60, 2^60]"},
    {"plane_offset_overflow.nff", 2, "a plane offset d / |n| beyond the float range"},
    // Found by fuzz/obj_fuzz.cpp: assimp leaks while it rejects this file (docs/robustness.md).
    {"assimp_leak_point_face.obj", 0, "assimp: "},
    {"truncated_header.ply", 9, "unexpected end of file: expected a PLY header keyword"},
    {"truncated_in_vertices.ply", 4, "announces 6 vertex elements"},
    {"truncated_in_faces.ply", 20, "unexpected end of file: expected 5 face elements, got 4"},
    {"ply_index_out_of_range.ply", 20, "face index 9 out of range [0, 6)"},
    {"ply_without_y.ply", 4, "the element vertex needs exactly one property each of x, y and z"},
};

// gtest prints parameters it does not know as bytes.
void PrintTo(const BrokenFile& broken, std::ostream* out) {
    *out << broken.name;
}

class BrokenCorpus : public ::testing::TestWithParam<BrokenFile> {};

TEST_P(BrokenCorpus, ThrowsLoadErrorWithFileLineAndExpectation) {
    const BrokenFile& broken = GetParam();
    test::expect_load_error(corpus("broken") / broken.name, broken.line, broken.expected);
}

INSTANTIATE_TEST_SUITE_P(Files, BrokenCorpus, ::testing::ValuesIn(kBrokenFiles),
                         [](const ::testing::TestParamInfo<BrokenFile>& param) {
                             std::string name = param.param.name;
                             for (char& c : name)
                                 c = std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
                             return name;
                         });

TEST(BrokenInput, HugeCountsFailAtOnceWithoutAllocatingForThem) {
    for (const char* name : {"huge_vertex_count.off", "huge_face_count.off", "huge_polygon.off",
                             "huge_material_count.dsc", "huge_polygon.nff"}) {
        test::reset_largest_allocation();
        const auto start = std::chrono::steady_clock::now();
        EXPECT_THROW((void)load_scene(corpus("broken") / name), LoadError) << name;
        EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1)) << name;
        EXPECT_LT(test::largest_allocation(), std::size_t{1} << 16) << name;
    }
}

TEST(BrokenInput, MissingFilesAndFoldersAreLoadErrorsWithoutLine) {
    for (const char* name :
         {"no_such_file.off", "no_such_file.dsc", "no_such_file.nff", "no_such_file.ply", "no_such_file"}) {
        test::expect_load_error(corpus("broken") / name, 0, "cannot open file: no such file");
    }
    test::expect_load_error(corpus("broken"), 0, "cannot open file: not a regular file");
}

TEST(BrokenInput, BinaryGarbageIsALoadErrorInEveryFormat) {
    test::ScratchDir dir;
    std::mt19937 random(20240531);
    for (const char* extension : {".off", ".dsc", ".nff", ".ply", ".obj", ".stl", ".xyz"}) {
        for (int sample = 0; sample < 8; ++sample) {
            std::string bytes(static_cast<std::size_t>(random() % 4096) + 1, '\0');
            for (char& byte : bytes)
                byte = static_cast<char>(random() & 0xff);
            const auto file = dir.write("garbage" + std::to_string(sample) + extension, bytes);
            EXPECT_THROW((void)load_scene(file), LoadError) << file;
        }
    }
}

TEST(BrokenInput, GarbageTokensAreQuotedPrintably) {
    test::ScratchDir dir;
    const auto file = dir.write("binary.off", std::string("OFF\n1 0 0\n\x01\x02\xff 0 0\n", 18));
    try {
        (void)load_scene(file);
        ADD_FAILURE() << "no LoadError";
    } catch (const LoadError& error) {
        EXPECT_NE(std::string(error.what()).find("got '\\x01\\x02\\xff'"), std::string::npos) << error.what();
    }
}

// Every prefix of a good file either loads or throws LoadError: no crash, no other exception, no hang.
void expect_every_truncation_handled(const std::filesystem::path& good, const std::string& stem,
                                     const std::vector<std::string>& companions = {}) {
    std::ostringstream text;
    text << std::ifstream(good, std::ios::binary).rdbuf();
    const std::string bytes = text.str();
    test::ScratchDir dir;
    for (const std::string& companion : companions) {
        std::ostringstream companion_text;
        companion_text << std::ifstream(good.parent_path() / companion, std::ios::binary).rdbuf();
        (void)dir.write(companion, companion_text.str());
    }
    for (std::size_t size = 0; size < bytes.size(); ++size) {
        const auto file = dir.write(stem, std::string_view(bytes).substr(0, size));
        try {
            (void)load_scene(file);
        } catch (const LoadError&) {
            // A clean refusal is what is asked for.
        } catch (const std::exception& other) {
            ADD_FAILURE() << "cut at " << size << ": " << other.what();
        }
    }
}

TEST(BrokenInput, EveryTruncationOfAGoodFileIsHandled) {
    expect_every_truncation_handled(corpus("good/quad_pentagon.off"), "cut.off");
    expect_every_truncation_handled(corpus("good/every_keyword.nff"), "cut.nff");
    expect_every_truncation_handled(corpus("good/scene.dsc"), "scene.dsc", {"scene.off"});
    expect_every_truncation_handled(corpus("good/order.ply"), "cut.ply");
}

// A few bytes of a good file replaced, at random, many times over: the same promise as for truncations.
void expect_random_damage_handled(const std::filesystem::path& good, const std::string& name,
                                  const std::vector<std::string>& companions = {}) {
    std::ostringstream text;
    text << std::ifstream(good, std::ios::binary).rdbuf();
    const std::string bytes = text.str();
    test::ScratchDir dir;
    for (const std::string& companion : companions) {
        std::ostringstream companion_text;
        companion_text << std::ifstream(good.parent_path() / companion, std::ios::binary).rdbuf();
        (void)dir.write(companion, companion_text.str());
    }
    // Bytes that turn numbers into other numbers, keywords or separators, and arbitrary ones.
    constexpr std::string_view telling = "0123456789-+.eE \n#npsfcx";
    std::mt19937 random(7);
    for (int variant = 0; variant < 500; ++variant) {
        std::string damaged = bytes;
        for (int change = 0; change < 1 + static_cast<int>(random() % 4); ++change) {
            const std::size_t at = random() % damaged.size();
            damaged[at] =
                random() % 2 == 0 ? telling[random() % telling.size()] : static_cast<char>(random() & 0xff);
        }
        const auto file = dir.write(name, damaged);
        try {
            (void)load_scene(file);
        } catch (const LoadError&) {
            // A clean refusal is what is asked for.
        } catch (const std::exception& other) {
            ADD_FAILURE() << "variant " << variant << ": " << other.what();
        }
    }
}

TEST(BrokenInput, RandomByteDamageIsHandled) {
    expect_random_damage_handled(corpus("good/quad_pentagon.off"), "damaged.off");
    expect_random_damage_handled(corpus("good/comments_colours.off"), "damaged.off");
    expect_random_damage_handled(corpus("good/every_keyword.nff"), "damaged.nff");
    expect_random_damage_handled(corpus("good/scene.dsc"), "scene.dsc", {"scene.off"});
    expect_random_damage_handled(corpus("good/order.ply"), "damaged.ply");
}

TEST(LoadErrorMessage, ReadsFileLineMessage) {
    EXPECT_STREQ(LoadError("dir/mesh.off", 12, "expected 3 vertex coordinates, got 'abc'").what(),
                 "dir/mesh.off:12: expected 3 vertex coordinates, got 'abc'");
    EXPECT_STREQ(LoadError("dir/mesh.ply", 0, "assimp: bad").what(), "dir/mesh.ply: assimp: bad");
    const LoadError error("x.nff", 3, "m");
    EXPECT_EQ(error.file(), std::filesystem::path("x.nff"));
    EXPECT_EQ(error.line(), 3u);
}

}  // namespace
}  // namespace lancer
