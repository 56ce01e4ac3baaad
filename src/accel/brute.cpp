#include "accel/brute.hpp"

namespace lancer {

template class SingleRayAccel<BruteAccel>;

AccelStats BruteAccel::stats() const {
    AccelStats stats;
    stats.primitives = geometry_.size();
    stats.nodes = 1;
    stats.leaves = 1;
    stats.empty_leaves = geometry_.size() == 0 ? 1 : 0;
    stats.references = geometry_.size();
    stats.mean_refs_per_leaf = static_cast<double>(geometry_.size());
    stats.max_refs_per_leaf = geometry_.size();
    return stats;
}

}  // namespace lancer
