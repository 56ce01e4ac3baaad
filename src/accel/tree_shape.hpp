// The shape the hierarchies measure of themselves (the counts of Ferreira & Mendoza 2011), and the figures it
// makes in AccelStats. A structure publishes them with its own figures (its SAH cost, each with what it
// means).
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "lancer/accel.hpp"

namespace lancer {

struct TreeShape {
    std::size_t nodes = 0;  // inner nodes and leaves
    std::size_t leaves = 0;
    std::size_t empty_leaves = 0;
    std::size_t references = 0;  // primitive references in the leaves, duplicates included
    int max_depth = 0;
    double mean_depth = 0.0;
    double mean_refs_per_leaf = 0.0;  // over the leaves that hold any
    std::size_t max_refs_per_leaf = 0;
};

// nodes, leaves, empty_leaves, references, max_depth, mean_depth, mean_refs_per_leaf, max_refs_per_leaf.
[[nodiscard]] std::vector<AccelFigure> tree_figures(const TreeShape& shape);

[[nodiscard]] inline AccelFigure count_figure(std::string key, std::size_t count, std::string help) {
    return {std::move(key), static_cast<double>(count), true, std::move(help)};
}
[[nodiscard]] inline AccelFigure value_figure(std::string key, double value, std::string help) {
    return {std::move(key), value, false, std::move(help)};
}

}  // namespace lancer
