#include "core/checked_points.hpp"

#include <algorithm>
#include <cmath>

#include "core/parallel.hpp"
#include "lancer/ray.hpp"

namespace lancer {
namespace {

// Points per task: enough that a task costs more than its scheduling.
constexpr std::size_t kPointGrain = 1 << 15;

// The box of the floats [first, last) (three per point), and whether one is NaN or outside the domain. 48
// floats (16 points) a step, so that each lane of the accumulators always holds one axis and the loop
// vectorises; `x < y ? x : y` keeps y for a NaN x, which the domain test reports anyway.
struct ChunkBox {
    Box3f box;
    bool outside = false;
};

ChunkBox chunk_box(const float* first, const float* last) {
    constexpr std::size_t kStep = 48;
    float lo[kStep], hi[kStep];
    std::fill_n(lo, kStep, kInfinity);
    std::fill_n(hi, kStep, -kInfinity);
    unsigned outside = 0;
    auto visit = [&](std::size_t slot, float x) {
        lo[slot] = x < lo[slot] ? x : lo[slot];
        hi[slot] = x > hi[slot] ? x : hi[slot];
        outside |= std::fabs(x) <= kCoordinateLimit ? 0u : 1u;
    };
    const auto count = static_cast<std::size_t>(last - first);
    std::size_t i = 0;
    for (; i + kStep <= count; i += kStep) {
        for (std::size_t slot = 0; slot < kStep; ++slot)
            visit(slot, first[i + slot]);
    }
    for (std::size_t slot = 0; i + slot < count; ++slot)
        visit(slot, first[i + slot]);
    ChunkBox chunk;
    for (std::size_t slot = 0; slot < kStep; ++slot) {
        const int axis = static_cast<int>(slot % 3);
        chunk.box.lo[axis] = std::min(chunk.box.lo[axis], lo[slot]);
        chunk.box.hi[axis] = std::max(chunk.box.hi[axis], hi[slot]);
    }
    chunk.outside = outside != 0;
    return chunk;
}

CheckedPoints merged(CheckedPoints a, const CheckedPoints& b) {
    a.box.extend(b.box);
    a.first_outside = std::min(a.first_outside, b.first_outside);
    return a;
}

}  // namespace

CheckedPoints check_points(std::span<const float> coordinates, std::size_t points_per_item) {
    const std::size_t item_floats = 3 * points_per_item;
    const std::size_t items = coordinates.size() / item_floats;
    const std::size_t grain = std::max<std::size_t>(1, kPointGrain / points_per_item);
    return parallel::reduce(
        0, items, grain, CheckedPoints{},
        [&](std::size_t from, std::size_t to, CheckedPoints checked) {
            const ChunkBox chunk =
                chunk_box(coordinates.data() + item_floats * from, coordinates.data() + item_floats * to);
            CheckedPoints points{chunk.box, CheckedPoints::kNone};
            // Which item: a second look at this chunk only.
            for (std::size_t i = from;
                 chunk.outside && i < to && points.first_outside == CheckedPoints::kNone; ++i) {
                for (std::size_t f = item_floats * i; f < item_floats * (i + 1); ++f) {
                    if (!(std::fabs(coordinates[f]) <= kCoordinateLimit)) points.first_outside = i;
                }
            }
            return merged(checked, points);
        },
        merged);
}

}  // namespace lancer
