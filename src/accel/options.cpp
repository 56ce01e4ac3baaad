// `--set KEY=VALUE`: structure options from the command line, checked and with the accepted range in the
// error message.
#include <algorithm>
#include <charconv>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/isa.hpp"

namespace lancer {
namespace {

[[noreturn]] void fail(std::string_view key, std::string_view value, std::string_view expected) {
    throw std::invalid_argument("--set " + std::string(key) + "=" + std::string(value) + ": expected " +
                                std::string(expected));
}

template <class Number>
Number parse_number(std::string_view key, std::string_view value, Number lowest, Number highest) {
    Number number{};
    const auto [end, error] = std::from_chars(value.data(), value.data() + value.size(), number);
    if (error != std::errc{} || end != value.data() + value.size() ||
        !(number >= lowest && number <= highest)) {
        fail(key, value, "a number in [" + std::to_string(lowest) + ", " + std::to_string(highest) + "]");
    }
    return number;
}

bool parse_bool(std::string_view key, std::string_view value) {
    if (value == "true" || value == "1") return true;
    if (value == "false" || value == "0") return false;
    fail(key, value, "true or false");
}

// Shortest text that reads back as the same number.
template <class Number>
std::string number_text(Number number) {
    char text[32];
    const auto end = std::to_chars(text, text + sizeof text, number).ptr;
    return std::string(text, end);
}

// One `--set` key: its help, the values it accepts, how to show a value and how to set one.
struct Option {
    std::string_view key;
    std::string_view help;
    std::string accepted;
    std::function<std::string(const BuildOptions&)> show;
    std::function<void(BuildOptions&, std::string_view key, std::string_view value)> set;
};

// A number field of one structure's options, in [lowest, highest].
template <class Group, class Number>
Option number(std::string_view key, std::string_view help, Group BuildOptions::*group, Number Group::*field,
              Number lowest, Number highest) {
    // Appended, not concatenated: GCC 12's -Wrestrict misreads `"[" + a + ...` here (GCC bug 105329).
    std::string range = "[";
    range.append(number_text(lowest)).append(", ").append(number_text(highest)).append("]");
    return {key, help, std::move(range), [=](const BuildOptions& o) { return number_text(o.*group.*field); },
            [=](BuildOptions& o, std::string_view k, std::string_view v) {
                o.*group.*field = parse_number(k, v, lowest, highest);
            }};
}

template <class Group>
Option flag(std::string_view key, std::string_view help, Group BuildOptions::*group, bool Group::*field) {
    return {
        key, help, "true, false", [=](const BuildOptions& o) { return o.*group.*field ? "true" : "false"; },
        [=](BuildOptions& o, std::string_view k, std::string_view v) { o.*group.*field = parse_bool(k, v); }};
}

// A field that takes one of a few named values; field(options) is a reference to it (a generic lambda, so
// that it reads const options too).
template <class Value, class Field>
Option choice(std::string_view key, std::string_view help,
              std::vector<std::pair<std::string_view, Value>> names, Field field) {
    std::string accepted;
    for (const auto& [name, value] : names)
        accepted += (accepted.empty() ? "" : ", ") + std::string(name);
    return {key, help, accepted,
            [=](const BuildOptions& o) {
                for (const auto& [name, value] : names) {
                    if (value == field(o)) return std::string(name);
                }
                return std::string("?");
            },
            [=](BuildOptions& o, std::string_view k, std::string_view v) {
                for (const auto& [name, value] : names) {
                    if (v == name) {
                        field(o) = value;
                        return;
                    }
                }
                fail(k, v, "one of " + accepted);
            }};
}

// The accepted values as listed, whatever this CPU runs; a request for more than it runs fails here, not at
// the build.
Option simd_isa_option() {
    return {"simd.isa",
            "the instruction set of bvh8_packet's kernels, of those this build and CPU run; auto: the widest",
            "auto, avx2, avx512", [](const BuildOptions& o) { return std::string(isa_name(o.isa)); },
            [](BuildOptions& o, std::string_view k, std::string_view v) {
                for (SimdIsa isa : {SimdIsa::Auto, SimdIsa::Avx2, SimdIsa::Avx512}) {
                    if (v == isa_name(isa) && isa_available(isa)) {
                        o.isa = isa;
                        return;
                    }
                }
                std::string accepted = "auto";
                for (SimdIsa isa : available_isas())
                    accepted += ", " + std::string(isa_name(isa));
                fail(k, v, "one of " + accepted + " (the instruction sets this build and CPU run)");
            }};
}

// Every `--set` key, grouped by structure, in the order `lancer info --options` lists them.
const std::vector<Option>& options_table() {
    using O = BuildOptions;
    static const std::vector<Option> table = {
        number("grid.density", "the cube root of the cells per primitive", &O::grid, &GridOptions::density,
               0.01f, 64.0f),
        number("octree.max_depth", "deepest level of the classic octree", &O::octree,
               &OctreeOptions::max_depth, 0, 20),
        number("octree.leaf_size", "references a node may hold before it is split", &O::octree,
               &OctreeOptions::leaf_size, 1, 1 << 20),
        number("plucker.max_depth", "deepest level of the Pluecker octree; 0: round(0.8 log2(N) - 5)",
               &O::plucker, &PluckerOptions::max_depth, 0, 16),
        number("plucker.leaf_size", "references a cell may hold before it is split", &O::plucker,
               &PluckerOptions::leaf_size, 1, 1 << 20),
        flag("plucker.balanced", "the 2:1 rule and links to leaves (the seed's layout)", &O::plucker,
             &PluckerOptions::balanced),
        flag("plucker.stored_boxes", "cell boxes stored, not recomputed from coordinates and level",
             &O::plucker, &PluckerOptions::stored_boxes),
        flag("plucker.morton", "cells in depth-first (Morton) order", &O::plucker, &PluckerOptions::morton),
        choice<KdTreeCost>(
            "kdtree.cost", "the split cost: Wald & Havran's SAH, or seed 003's",
            {{"wald-havran", KdTreeCost::WaldHavran}, {"seed003", KdTreeCost::Seed003}},
            [](auto& o) -> auto& { return o.kdtree.cost; }),
        number("kdtree.traversal_cost", "the SAH's cost of a traversal step", &O::kdtree,
               &KdTreeOptions::traversal_cost, 0.0f, 1e6f),
        number("kdtree.intersection_cost", "the SAH's cost of a primitive test", &O::kdtree,
               &KdTreeOptions::intersection_cost, 1e-3f, 1e6f),
        number("kdtree.empty_bonus", "the SAH's bonus for an empty side", &O::kdtree,
               &KdTreeOptions::empty_bonus, 0.0f, 1.0f),
        number("kdtree.max_depth", "deepest level; 0: 8 + 1.3 log2(N)", &O::kdtree, &KdTreeOptions::max_depth,
               0, 64),
        choice<BvhBuilder>(
            "bvh.builder", "the SAH builder: binned, or a full sweep (seed 002)",
            {{"binned", BvhBuilder::BinnedSah}, {"sweep", BvhBuilder::SweepSah}},
            [](auto& o) -> auto& { return o.bvh.builder; }),
        number("bvh.max_leaf_size", "primitives a leaf may hold (also bvh4, bvh8)", &O::bvh,
               &BvhOptions::max_leaf_size, 1, 64),
        number("bvh.bins", "bins of the binned builder", &O::bvh, &BvhOptions::bins, 2, 256),
        flag("bvh.spatial_splits", "spatial splits in the binned builder (the SBVH)", &O::bvh,
             &BvhOptions::spatial_splits),
        choice<EmbreeQuality>(
            "embree.quality",
            "Embree's build quality (its robust mode, the watertight test, builds without "
            "spatial splits)",
            {{"high", EmbreeQuality::High}, {"medium", EmbreeQuality::Medium}},
            [](auto& o) -> auto& { return o.embree_quality; }),
        simd_isa_option(),
    };
    return table;
}

}  // namespace

void set_build_option(BuildOptions& options, std::string_view assignment) {
    const auto equals = assignment.find('=');
    const std::string_view key = assignment.substr(0, equals);
    const auto& table = options_table();
    const auto option =
        std::find_if(table.begin(), table.end(), [&](const Option& o) { return o.key == key; });
    if (equals == std::string_view::npos || option == table.end()) {
        std::string known;
        for (const Option& each : table)
            known += (known.empty() ? "" : ", ") + std::string(each.key);
        throw std::invalid_argument("--set " + std::string(assignment) +
                                    ": expected KEY=VALUE with KEY one of " + known);
    }
    option->set(options, key, assignment.substr(equals + 1));
}

std::vector<BuildOptionInfo> build_option_infos() {
    const BuildOptions defaults;
    std::vector<BuildOptionInfo> infos;
    for (const Option& option : options_table())
        infos.push_back(
            {std::string(option.key), option.accepted, option.show(defaults), std::string(option.help)});
    return infos;
}

}  // namespace lancer
