// What the subcommands share: loading with timing, building a structure with timing, parallel batches,
// and the error type that maps to exit code 2.
#pragma once

#include <chrono>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "lancer/accel.hpp"
#include "lancer/load_scene.hpp"
#include "lancer/scene.hpp"
#include "lancer/world.hpp"

namespace lancer::cli {

// Bad input from the user (a file, a flag value): printed on stderr, exit code 2.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// A check the command ran failed (structures disagree in the bench): printed on stderr, exit code 1.
class CheckFailure : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

class Stopwatch {
  public:
    [[nodiscard]] double elapsed_ms() const {
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
    }

  private:
    std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

struct LoadedScene {
    Scene scene;
    double load_ms = 0.0;
};

// Throws LoadError, or InputError when loading passes --max-memory.
[[nodiscard]] LoadedScene load_timed(const std::filesystem::path& file, const LoadOptions& options = {});

// --max-memory SIZE (512M, 2G): the bound of include/lancer/memory_limit.hpp, set as soon as the flag is
// parsed, so that loading and building run under it. AccelChoice::add_options adds it.
void add_memory_limit_option(CLI::App& command);

// The InputError for a std::bad_alloc that `subject` met while `phase` ("building octree"): "needs more
// than --max-memory 512M" under a limit, "ran out of memory" without one. Lifts the limit first, so that the
// message itself can be allocated.
[[nodiscard]] InputError out_of_memory(const std::string& subject, const std::string& phase);

// The structure a command builds: --accel NAME, --watertight, --set KEY=VALUE (repeatable).
struct AccelChoice {
    std::string name = "bvh";
    bool watertight = false;
    std::vector<std::string> settings;
    const CLI::Option* name_option = nullptr;  // to tell `--accel bvh` from the default

    void add_options(CLI::App& command);
    // Throws InputError for a malformed --set.
    [[nodiscard]] BuildOptions build_options() const;
};

struct BuiltAccel {
    std::unique_ptr<Accel> accel;
    double build_ms = 0.0;
};

// Throws InputError for an unknown structure name, a malformed --set or a build that passes --max-memory.
[[nodiscard]] BuiltAccel build_timed(const AccelChoice& choice, const Geometry& geometry);

// What a command works on: a scene file with the chosen structure built on it, or a Plücker octree file
// (`.plo`, written by `lancer convert`) with the geometry it holds, loaded instead of built (build_ms 0,
// load_ms the read and the checks). A `.plo` file takes --watertight but not --set, and --accel only as
// plucker. Throws LoadError, InputError.
struct PreparedScene {
    World world;
    double load_ms = 0.0;
    double build_ms = 0.0;
};
[[nodiscard]] PreparedScene prepare_scene(const std::filesystem::path& file, const AccelChoice& choice);
// prepare_scene's World of a scene already loaded.
[[nodiscard]] PreparedScene prepare_loaded(LoadedScene loaded, const AccelChoice& choice);

[[nodiscard]] bool stderr_is_terminal();

// "1024x768" -> {1024, 768}; throws InputError otherwise.
[[nodiscard]] std::pair<int, int> parse_size(const std::string& text);

// The transform of an option that takes one of a few names, in any case: each name becomes its text (what
// CLI11 then converts to the option's type), and any other word is refused with "--mode: 'sepia' is not one
// of whitted, flat, ...", the names in the order given.
[[nodiscard]] CLI::Validator one_of(std::vector<std::pair<std::string, std::string>> names_to_text);

// The same for a string option: the name itself, in the case given here.
[[nodiscard]] CLI::Validator one_of(const std::vector<std::string>& names);

// The same for an enum option: each name becomes its enumerator.
template <class Enum>
requires std::is_enum_v<Enum>
[[nodiscard]] CLI::Validator one_of(const std::vector<std::pair<std::string, Enum>>& names) {
    std::vector<std::pair<std::string, std::string>> names_to_text;
    for (const auto& [name, value] : names)
        names_to_text.emplace_back(name, std::to_string(static_cast<std::underlying_type_t<Enum>>(value)));
    return one_of(std::move(names_to_text));
}

}  // namespace lancer::cli
