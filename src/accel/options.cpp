// `--set KEY=VALUE`: structure options from the command line, checked and with the accepted range in the
// error message.
#include <charconv>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>

#include "lancer/accel.hpp"

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

using Setter = std::function<void(BuildOptions&, std::string_view key, std::string_view value)>;

const std::map<std::string, Setter, std::less<>>& setters() {
    static const std::map<std::string, Setter, std::less<>> table = {
        {"grid.density",
         [](BuildOptions& o, auto k, auto v) { o.grid.density = parse_number(k, v, 0.01f, 64.0f); }},
        {"octree.max_depth",
         [](BuildOptions& o, auto k, auto v) { o.octree.max_depth = parse_number(k, v, 0, 20); }},
        {"octree.leaf_size",
         [](BuildOptions& o, auto k, auto v) { o.octree.leaf_size = parse_number(k, v, 1, 1 << 20); }},
        {"plucker.max_depth",
         [](BuildOptions& o, auto k, auto v) { o.plucker.max_depth = parse_number(k, v, 0, 16); }},
        {"plucker.leaf_size",
         [](BuildOptions& o, auto k, auto v) { o.plucker.leaf_size = parse_number(k, v, 1, 1 << 20); }},
        {"plucker.balanced", [](BuildOptions& o, auto k, auto v) { o.plucker.balanced = parse_bool(k, v); }},
        {"plucker.stored_boxes",
         [](BuildOptions& o, auto k, auto v) { o.plucker.stored_boxes = parse_bool(k, v); }},
        {"plucker.morton", [](BuildOptions& o, auto k, auto v) { o.plucker.morton = parse_bool(k, v); }},
        {"kdtree.cost",
         [](BuildOptions& o, auto k, auto v) {
             if (v == "wald-havran") {
                 o.kdtree.cost = KdTreeCost::WaldHavran;
             } else if (v == "seed003") {
                 o.kdtree.cost = KdTreeCost::Seed003;
             } else {
                 fail(k, v, "wald-havran or seed003");
             }
         }},
        {"kdtree.traversal_cost",
         [](BuildOptions& o, auto k, auto v) { o.kdtree.traversal_cost = parse_number(k, v, 0.0f, 1e6f); }},
        {"kdtree.intersection_cost",
         [](BuildOptions& o, auto k, auto v) {
             o.kdtree.intersection_cost = parse_number(k, v, 1e-3f, 1e6f);
         }},
        {"kdtree.empty_bonus",
         [](BuildOptions& o, auto k, auto v) { o.kdtree.empty_bonus = parse_number(k, v, 0.0f, 1.0f); }},
        {"kdtree.max_depth",
         [](BuildOptions& o, auto k, auto v) { o.kdtree.max_depth = parse_number(k, v, 0, 64); }},
        {"bvh.builder",
         [](BuildOptions& o, auto k, auto v) {
             if (v == "sweep") {
                 o.bvh.builder = BvhBuilder::SweepSah;
             } else if (v == "binned") {
                 o.bvh.builder = BvhBuilder::BinnedSah;
             } else {
                 fail(k, v, "sweep or binned");
             }
         }},
        {"bvh.max_leaf_size",
         [](BuildOptions& o, auto k, auto v) { o.bvh.max_leaf_size = parse_number(k, v, 1, 64); }},
        {"embree.quality",
         [](BuildOptions& o, auto k, auto v) {
             if (v == "high") {
                 o.embree_quality = EmbreeQuality::High;
             } else if (v == "medium") {
                 o.embree_quality = EmbreeQuality::Medium;
             } else {
                 fail(k, v, "high or medium");
             }
         }},
        {"bvh.bins", [](BuildOptions& o, auto k, auto v) { o.bvh.bins = parse_number(k, v, 2, 256); }},
        {"bvh.spatial_splits",
         [](BuildOptions& o, auto k, auto v) { o.bvh.spatial_splits = parse_bool(k, v); }},
        {"simd.isa",
         [](BuildOptions& o, auto k, auto v) {
             // Only what this build and CPU run: a request for more fails here, not at the build.
             for (SimdIsa isa : {SimdIsa::Auto, SimdIsa::Avx2, SimdIsa::Avx512}) {
                 if (v == isa_name(isa) && isa_available(isa)) {
                     o.isa = isa;
                     return;
                 }
             }
             std::string accepted = "auto";
             for (SimdIsa isa : available_isas())
                 accepted += " or " + std::string(isa_name(isa));
             fail(k, v, accepted + " (the instruction sets this build and CPU run)");
         }},
    };
    return table;
}

}  // namespace

void set_build_option(BuildOptions& options, std::string_view assignment) {
    const auto equals = assignment.find('=');
    const std::string_view key = assignment.substr(0, equals);
    const auto setter = setters().find(key);
    if (equals == std::string_view::npos || setter == setters().end()) {
        std::string known;
        for (const auto& [name, unused] : setters())
            known += (known.empty() ? "" : ", ") + name;
        throw std::invalid_argument("--set " + std::string(assignment) +
                                    ": expected KEY=VALUE with KEY one of " + known);
    }
    setter->second(options, key, assignment.substr(equals + 1));
}

}  // namespace lancer
