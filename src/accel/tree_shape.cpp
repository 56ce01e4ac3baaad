#include "accel/tree_shape.hpp"

namespace lancer {

std::vector<AccelFigure> tree_figures(const TreeShape& shape) {
    return {count_figure("nodes", shape.nodes, "inner nodes and leaves"),
            count_figure("leaves", shape.leaves, "leaves"),
            count_figure("empty_leaves", shape.empty_leaves, "leaves that hold no primitive"),
            count_figure("references", shape.references,
                         "primitive references in the leaves, duplicates included"),
            count_figure("max_depth", static_cast<std::size_t>(shape.max_depth),
                         "depth of the deepest leaf, the root's 0"),
            value_figure("mean_depth", shape.mean_depth, "mean depth of the leaves"),
            value_figure("mean_refs_per_leaf", shape.mean_refs_per_leaf,
                         "mean references of the leaves that hold any"),
            count_figure("max_refs_per_leaf", shape.max_refs_per_leaf, "most references in one leaf")};
}

}  // namespace lancer
