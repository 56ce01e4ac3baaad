// The `--set` keys of the structures' option groups (lancer::BuildOptions::group). Each structure lists its
// group's keys next to its code (option_rows, named in its registry line); the registry gathers them for
// set_build_option, build_option_infos and `lancer info --options`.
#pragma once

#include <charconv>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lancer/accel.hpp"

namespace lancer {

// One key: its help, the values it accepts, how to show a value and how to set one (throwing
// std::invalid_argument that names the key and the values it accepts).
struct BuildOptionRow {
    std::string key;  // "bvh.builder"
    std::string help;
    std::string accepted;
    std::function<std::string(const BuildOptions&)> show;
    std::function<void(BuildOptions&, std::string_view value)> set;
};

[[noreturn]] void fail_option(std::string_view key, std::string_view value, std::string_view expected);

// Shortest text that reads back as the same number.
template <class Number>
[[nodiscard]] std::string number_text(Number number) {
    char text[32];
    const auto end = std::to_chars(text, text + sizeof text, number).ptr;
    return std::string(text, end);
}

// "group.name": a key of Group's.
template <class Group>
[[nodiscard]] std::string group_key(std::string_view name) {
    std::string key(Group::kGroup);
    return key.append(".").append(name);
}

// A number field of Group, in [lowest, highest]; its key is group_key<Group>(name).
template <class Group, class Number>
[[nodiscard]] BuildOptionRow number_option(std::string_view name, std::string_view help, Number Group::*field,
                                           Number lowest, Number highest) {
    const std::string key = group_key<Group>(name);
    // Appended, not concatenated: GCC 12's -Wrestrict misreads `"[" + a + ...` here (GCC bug 105329).
    std::string range = "[";
    range.append(number_text(lowest)).append(", ").append(number_text(highest)).append("]");
    return {key, std::string(help), range,
            [=](const BuildOptions& o) { return number_text(o.group<Group>().*field); },
            [=](BuildOptions& o, std::string_view value) {
                Number number{};
                const auto [end, error] = std::from_chars(value.data(), value.data() + value.size(), number);
                if (error != std::errc{} || end != value.data() + value.size() ||
                    !(number >= lowest && number <= highest)) {
                    fail_option(key, value, "a number in " + range);
                }
                o.group<Group>().*field = number;
            }};
}

// A true/false field of Group.
template <class Group>
[[nodiscard]] BuildOptionRow flag_option(std::string_view name, std::string_view help, bool Group::*field) {
    const std::string key = group_key<Group>(name);
    return {key, std::string(help), "true, false",
            [=](const BuildOptions& o) { return std::string(o.group<Group>().*field ? "true" : "false"); },
            [=](BuildOptions& o, std::string_view value) {
                if (value == "true" || value == "1") {
                    o.group<Group>().*field = true;
                } else if (value == "false" || value == "0") {
                    o.group<Group>().*field = false;
                } else {
                    fail_option(key, value, "true or false");
                }
            }};
}

// A field of Group that takes one of a few named values.
template <class Group, class Value>
[[nodiscard]] BuildOptionRow choice_option(std::string_view name, std::string_view help, Value Group::*field,
                                           std::vector<std::pair<std::string_view, Value>> names) {
    const std::string key = group_key<Group>(name);
    std::string accepted;
    for (const auto& [value_name, value] : names)
        accepted.append(accepted.empty() ? "" : ", ").append(value_name);
    return {key, std::string(help), accepted,
            [=](const BuildOptions& o) {
                for (const auto& [value_name, value] : names) {
                    if (value == o.group<Group>().*field) return std::string(value_name);
                }
                return std::string("?");
            },
            [=](BuildOptions& o, std::string_view text) {
                for (const auto& [value_name, value] : names) {
                    if (text == value_name) {
                        o.group<Group>().*field = value;
                        return;
                    }
                }
                fail_option(key, text, "one of " + accepted);
            }};
}

// The keys every structure shares (options.cpp).
[[nodiscard]] std::vector<BuildOptionRow> shared_option_rows();

// Every key of the registered structures' groups, each once, in registry order, then the shared ones
// (registry.cpp).
[[nodiscard]] std::vector<BuildOptionRow> option_rows();

}  // namespace lancer
