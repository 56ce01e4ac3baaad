// Helpers shared by the loader tests: where the authored corpus and the shared data live, a scratch folder
// for files written by a test, and the check every bad input must pass.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "lancer/load_scene.hpp"

namespace lancer::test {

namespace fs = std::filesystem;

inline fs::path corpus(std::string_view name) {
    return fs::path(LANCER_SOURCE_DIR) / "tests/scene/data" / name;
}

// The six vertices of the corpus's order.obj and order.ply, and of ply_loader_test.cpp's binary PLY files.
inline const std::vector<Vec3f> kOrderVertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0},
                                                  {0, 0, 1}, {1, 1, 1}, {2, 0, 0}};

// shared/data, or an empty path when this checkout has no shared data (tests then skip).
inline fs::path shared_data() {
    const fs::path data = fs::path(LANCER_SHARED_DIR) / "data";
    return fs::is_directory(data) ? data : fs::path();
}

// A folder of its own per test, removed afterwards.
class ScratchDir {
  public:
    ScratchDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        std::string name = "lancer_scene_" + std::string(info->test_suite_name()) + "_" + info->name();
        for (char& c : name)
            c = c == '/' ? '_' : c;  // parameterised tests have '/' in their names
        dir_ = fs::temp_directory_path() / name;
        fs::remove_all(dir_);
        fs::create_directories(dir_);
    }
    ~ScratchDir() { fs::remove_all(dir_); }
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;

    [[nodiscard]] fs::path write(const std::string& name, std::string_view bytes) const {
        const fs::path path = dir_ / name;
        std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        return path;
    }
    [[nodiscard]] const fs::path& path() const { return dir_; }

  private:
    fs::path dir_;
};

// load_scene(file) must throw a LoadError for `error_file` (the file itself unless given) at `line`
// (0: none) whose message reads "FILE:LINE: ..." and contains `expected`.
inline void expect_load_error(const fs::path& file, std::size_t line, std::string_view expected,
                              const fs::path& error_file = {}) {
    const fs::path blamed = error_file.empty() ? file : error_file;
    try {
        (void)load_scene(file);
        ADD_FAILURE() << "no LoadError for " << file;
    } catch (const LoadError& error) {
        const std::string what = error.what();
        EXPECT_EQ(error.file(), blamed) << what;
        EXPECT_EQ(error.line(), line) << what;
        const std::string prefix =
            blamed.string() + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": ";
        EXPECT_EQ(what.rfind(prefix, 0), 0u) << what << "\ndoes not start with " << prefix;
        EXPECT_NE(what.find(expected), std::string::npos) << what << "\ndoes not contain " << expected;
    }
}

}  // namespace lancer::test
