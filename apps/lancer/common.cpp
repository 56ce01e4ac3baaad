#include "common.hpp"

#include <unistd.h>

#include <cctype>
#include <charconv>
#include <new>

#include "lancer/load_scene.hpp"
#include "lancer/memory_limit.hpp"

namespace lancer::cli {

LoadedScene load_timed(const std::filesystem::path& file, const LoadOptions& options) {
    Stopwatch watch;
    try {
        LoadedScene loaded{load_scene(file, options), 0.0};
        loaded.load_ms = watch.elapsed_ms();
        return loaded;
    } catch (const std::bad_alloc&) {
        throw out_of_memory(file.string(), "loading");
    }
}

void add_memory_limit_option(CLI::App& command) {
    command
        .add_option_function<std::string>(
            "--max-memory",
            [](const std::string& size) {
                std::size_t limit = 0;
                try {
                    limit = parse_memory_size(size);
                } catch (const std::invalid_argument& error) {
                    throw CLI::ValidationError("--max-memory", error.what());
                }
                if (limit <= allocated_bytes()) {
                    throw CLI::ValidationError("--max-memory", size + " is less than the " +
                                                                   std::to_string(allocated_bytes()) +
                                                                   " bytes lancer has allocated at start");
                }
                set_memory_limit(limit);
            },
            "Bound on what loading and building may allocate, e.g. 512M, 2G (exit code 2 beyond it)")
        ->type_name("SIZE");
}

InputError out_of_memory(const std::string& subject, const std::string& phase) {
    const std::size_t limit = memory_limit();
    set_memory_limit(0);
    if (limit == 0) return InputError(subject + ": ran out of memory while " + phase);
    return InputError(subject + ": needs more than --max-memory " + format_memory_size(limit) + " while " +
                      phase);
}

void AccelChoice::add_options(CLI::App& command) {
    std::string names;
    for (std::string_view known : accel_names())
        names += (names.empty() ? "" : ", ") + std::string(known);
    name_option =
        command.add_option("--accel", name, "Acceleration structure: " + names)->capture_default_str();
    command.add_flag("--watertight", watertight, "Watertight triangle test (Woop, Benthin & Wald 2013)");
    command.add_option(
        "--set", settings,
        "Structure option KEY=VALUE, e.g. bvh.builder=sweep (repeatable; `lancer info --options` lists "
        "them)");
    add_memory_limit_option(command);
}

BuildOptions AccelChoice::build_options() const {
    BuildOptions options =
        lancer::build_options(watertight ? TriangleTest::Watertight : TriangleTest::MollerTrumbore);
    try {
        for (const std::string& setting : settings)
            set_build_option(options, setting);
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    }
    return options;
}

BuiltAccel build_timed(const AccelChoice& choice, const Geometry& geometry) {
    BuiltAccel built;
    const BuildOptions options = choice.build_options();
    try {
        built.accel = make_accel(choice.name);
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    }
    Stopwatch watch;
    try {
        built.accel->build(geometry, options);
    } catch (const std::bad_alloc&) {
        built.accel.reset();
        throw out_of_memory("the scene (" + std::to_string(geometry.size()) + " primitives)",
                            "building " + choice.name);
    }
    built.build_ms = watch.elapsed_ms();
    return built;
}

PreparedScene prepare_loaded(LoadedScene loaded, const AccelChoice& choice) {
    const BuildOptions options = choice.build_options();
    const std::size_t primitives = loaded.scene.triangle_count() + loaded.scene.spheres.size();
    Stopwatch watch;
    try {
        World world(std::move(loaded.scene), choice.name, options);
        return {std::move(world), loaded.load_ms, watch.elapsed_ms()};
    } catch (const std::invalid_argument& error) {
        throw InputError(error.what());
    } catch (const std::bad_alloc&) {
        throw out_of_memory("the scene (" + std::to_string(primitives) + " primitives)",
                            "building " + choice.name);
    }
}

PreparedScene prepare_scene(const std::filesystem::path& file, const AccelChoice& choice) {
    if (file.extension() != ".plo") return prepare_loaded(load_timed(file), choice);
    if (choice.name_option != nullptr && choice.name_option->count() > 0 && choice.name != "plucker")
        throw InputError(file.string() + " holds a plucker octree: --accel must be plucker or left out");
    if (!choice.settings.empty())
        throw InputError("--set does not apply to a stored structure: give the options to `lancer convert`");
    Stopwatch watch;
    try {
        World world = World::load_structure(
            file, choice.watertight ? std::optional(TriangleTest::Watertight) : std::nullopt);
        return {std::move(world), watch.elapsed_ms(), 0.0};
    } catch (const StructureFileError& error) {
        throw InputError(error.what());
    } catch (const std::bad_alloc&) {
        throw out_of_memory(file.string(), "loading");
    }
}

bool stderr_is_terminal() {
    return isatty(STDERR_FILENO) != 0;
}

std::pair<int, int> parse_size(const std::string& text) {
    const auto separator = text.find('x');
    int width = 0, height = 0;
    if (separator != std::string::npos) {
        const char* begin = text.data();
        const char* middle = begin + separator;
        const char* end = begin + text.size();
        auto [width_end, width_error] = std::from_chars(begin, middle, width);
        auto [height_end, height_error] = std::from_chars(middle + 1, end, height);
        if (width_error == std::errc{} && height_error == std::errc{} && width_end == middle &&
            height_end == end && width > 0 && height > 0 && width <= 32768 && height <= 32768) {
            return {width, height};
        }
    }
    throw InputError("--size: expected WIDTHxHEIGHT with both in [1, 32768], got '" + text + "'");
}

CLI::Validator one_of(std::vector<std::pair<std::string, std::string>> names_to_text) {
    const auto lower = [](std::string word) {
        for (char& c : word)
            c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        return word;
    };
    std::string names;
    for (const auto& entry : names_to_text)
        names += (names.empty() ? "" : ", ") + entry.first;
    return CLI::Validator(
        [table = std::move(names_to_text), names, lower](std::string& input) -> std::string {
            for (const auto& [name, text] : table) {
                if (lower(input) == lower(name)) {
                    input = text;
                    return {};
                }
            }
            return "'" + input + "' is not one of " + names;
        },
        "");
}

CLI::Validator one_of(const std::vector<std::string>& names) {
    std::vector<std::pair<std::string, std::string>> names_to_text;
    for (const std::string& name : names)
        names_to_text.emplace_back(name, name);
    return one_of(std::move(names_to_text));
}

}  // namespace lancer::cli
