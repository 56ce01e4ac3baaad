// The configurations the agreement tests run: every registered structure with its default options, the
// structures built on the binary BVH (bvh, bvh_packet, bvh4, bvh8, bvh8_packet) a second time with spatial
// splits (bvh.spatial_splits), which change their leaves, and bvh8_packet with its AVX2 kernels where its
// default ones are AVX-512 (docs/isa.md), so that both instruction sets are checked.
#pragma once

#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "accel/bvh/bvh.hpp"
#include "lancer/accel.hpp"

namespace lancer::testing {

struct Configuration {
    std::string_view name;
    bool spatial_splits = false;
    SimdIsa isa = SimdIsa::Auto;

    // A test name: the structure's, with "_spatial_splits" where they are on and the instruction set where
    // one is asked for.
    [[nodiscard]] std::string label() const {
        std::string label(name);
        if (spatial_splits) label.append("_spatial_splits");
        if (isa != SimdIsa::Auto) label.append("_").append(isa_name(isa));
        return label;
    }
    [[nodiscard]] BuildOptions options(TriangleTest test) const {
        BuildOptions options = build_options(test);
        options.group<BvhOptions>().spatial_splits = spatial_splits;
        options.isa = isa;
        return options;
    }
};

// How GoogleTest names a configuration in its messages and in CTest's test names.
inline void PrintTo(const Configuration& configuration, std::ostream* os) {
    *os << configuration.label();
}

[[nodiscard]] inline bool built_on_the_binary_bvh(std::string_view name) {
    return name == "bvh" || name == "bvh_packet" || name == "bvh4" || name == "bvh8" || name == "bvh8_packet";
}

// Each of `names` with its defaults, then those built on the binary BVH with spatial splits, then
// bvh8_packet with its AVX2 kernels where the default ones are AVX-512.
[[nodiscard]] inline std::vector<Configuration> agreement_configurations(
    const std::vector<std::string_view>& names) {
    std::vector<Configuration> configurations;
    for (const std::string_view name : names)
        configurations.push_back({name, false});
    for (const std::string_view name : names) {
        if (built_on_the_binary_bvh(name)) configurations.push_back({name, true});
    }
    for (const std::string_view name : names) {
        if (name == "bvh8_packet" && isa_available(SimdIsa::Avx512))
            configurations.push_back({name, false, SimdIsa::Avx2});
    }
    return configurations;
}

}  // namespace lancer::testing
