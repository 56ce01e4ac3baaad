// The configurations the agreement tests run: every registered structure with its default options, and the
// structures built on the binary BVH (bvh, bvh_packet, bvh4, bvh8, bvh8_packet) a second time with spatial
// splits (bvh.spatial_splits), which change their leaves.
#pragma once

#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "lancer/accel.hpp"

namespace lancer::testing {

struct Configuration {
    std::string_view name;
    bool spatial_splits = false;

    // A test name: the structure's, with "_spatial_splits" where they are on.
    [[nodiscard]] std::string label() const {
        return std::string(name) + (spatial_splits ? "_spatial_splits" : "");
    }
    [[nodiscard]] BuildOptions options(TriangleTest test) const {
        BuildOptions options = build_options(test);
        options.bvh.spatial_splits = spatial_splits;
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

// Each of `names` with its defaults, then those built on the binary BVH with spatial splits.
[[nodiscard]] inline std::vector<Configuration> with_spatial_splits(
    const std::vector<std::string_view>& names) {
    std::vector<Configuration> configurations;
    for (const std::string_view name : names)
        configurations.push_back({name, false});
    for (const std::string_view name : names) {
        if (built_on_the_binary_bvh(name)) configurations.push_back({name, true});
    }
    return configurations;
}

}  // namespace lancer::testing
