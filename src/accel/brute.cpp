#include "accel/brute.hpp"

#include "accel/tree_shape.hpp"

namespace lancer {

template class SingleRayAccel<BruteAccel>;

AccelStats BruteAccel::stats() const {
    AccelStats stats;
    stats.primitives = geometry_.size();
    stats.figures = {count_figure("references", geometry_.size(), "primitives each ray is tested against")};
    return stats;
}

}  // namespace lancer
