// What the walk tests expect of a leaf-to-leaf walk: the leaves a ray crosses, in the order it enters them,
// found from each leaf's slab interval independently of the walk.
#pragma once

#include <algorithm>
#include <cstdint>
#include <tuple>
#include <vector>

namespace lancer::testing {

// The leaves of `crossed`, each given as (entry, exit, leaf), by entry; ties by exit, then by leaf, so that
// the order is one whatever the order of the input.
inline std::vector<std::uint32_t> in_order_of_entry(
    std::vector<std::tuple<float, float, std::uint32_t>> crossed) {
    std::sort(crossed.begin(), crossed.end());
    std::vector<std::uint32_t> leaves;
    for (const auto& [entry, exit, leaf] : crossed)
        leaves.push_back(leaf);
    return leaves;
}

}  // namespace lancer::testing
