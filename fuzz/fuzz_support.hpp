// What every libFuzzer harness in fuzz/ shares: a scratch folder for the files the loaders read, the
// loader contract check and the way a broken contract is reported (docs/robustness.md, "Fuzzing").
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>

#include "lancer/scene.hpp"

namespace lancer::fuzz {

// Prints "lancer fuzz finding: WHAT" and aborts, so that libFuzzer saves the input as a crash.
[[noreturn]] void finding(std::string_view what);

// A folder of this process's own under $TMPDIR (scripts/fuzz.sh points it into build-fuzz/), removed at exit.
[[nodiscard]] const std::filesystem::path& scratch_dir();

// Writes the bytes to scratch_dir() / name, replacing what was there, and returns the path.
std::filesystem::path write_scratch_file(std::string_view name, std::string_view bytes);

// The promises of include/lancer/scene.hpp that load_scene makes (docs/formats.md): at least one material,
// finite vertices, indices and material ids in range, normals absent or one per vertex, finite spheres.
void check_scene_contract(const Scene& scene);

// The loader contract: load_scene(file) returns a scene that keeps check_scene_contract, or throws
// lancer::LoadError. Any other exception is a finding (a crash, a hang or a sanitizer report is one anyway).
void load_and_check(const std::filesystem::path& file);

// The bytes as text, for harnesses that take libFuzzer's input as a file's content.
[[nodiscard]] inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
    return {reinterpret_cast<const char*>(data), size};
}

}  // namespace lancer::fuzz
