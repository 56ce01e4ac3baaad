// The Stanford meshes of ../shared/data/meshes (README, "The Stanford meshes"), on which the long agreement
// tests run when the checkout has them: a suite derived from StanfordMeshTest, instantiated with
// stanford_meshes() and named by stanford_mesh_name.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>

#include "lancer/load_scene.hpp"
#include "lancer/scene.hpp"

namespace lancer::testing {

inline std::filesystem::path stanford_mesh_path(const char* file) {
    return std::filesystem::path(LANCER_SHARED_DIR) / "data" / "meshes" / file;
}

// A test on the mesh its parameter names, loaded before the test; skipped when the checkout lacks it.
class StanfordMeshTest : public ::testing::TestWithParam<const char*> {
  protected:
    void SetUp() override {
        const std::filesystem::path file = stanford_mesh_path(GetParam());
        if (!std::filesystem::exists(file))
            GTEST_SKIP() << file << " is absent (see README, 'The Stanford meshes')";
        geometry_ = std::make_unique<SceneGeometry>(load_scene(file));
    }
    [[nodiscard]] const SceneGeometry& mesh() const { return *geometry_; }

  private:
    std::unique_ptr<SceneGeometry> geometry_;
};

// The meshes' files, the smallest first.
inline auto stanford_meshes() {
    return ::testing::Values("bunny.obj", "armadillo.off", "dragon.ply");
}

// A mesh's part of a test name: its file name without the extension ("bunny").
inline std::string stanford_mesh_name(const ::testing::TestParamInfo<const char*>& info) {
    const std::string file(info.param);
    return file.substr(0, file.find('.'));
}

}  // namespace lancer::testing
