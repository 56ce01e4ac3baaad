// Box3f's queries, which the structure tests rely on to check that every node bounds what it holds: a
// containment that answered true too often would let those checks pass on a broken tree.
#include "lancer/box.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace lancer {
namespace {

constexpr float kLarge = std::numeric_limits<float>::max();

TEST(Box, ContainsBoxesFacesIncluded) {
    const Box3f outer{{-1, -2, -3}, {1, 2, 3}};
    EXPECT_TRUE(outer.contains(outer));
    EXPECT_TRUE(outer.contains(Box3f{{0, 0, 0}, {0, 0, 0}}));
    EXPECT_TRUE(outer.contains(Box3f{{-1, 0, 0}, {1, 2, 3}}));
    // Out by one float on each face in turn.
    for (int axis = 0; axis < 3; ++axis) {
        Box3f below = outer, above = outer;
        below.lo[axis] = std::nextafter(outer.lo[axis], -kLarge);
        above.hi[axis] = std::nextafter(outer.hi[axis], kLarge);
        EXPECT_FALSE(outer.contains(below)) << "axis " << axis;
        EXPECT_FALSE(outer.contains(above)) << "axis " << axis;
    }
    // Overlapping without containing, and containing the other way round.
    EXPECT_FALSE(outer.contains(Box3f{{0, 0, 0}, {2, 1, 1}}));
    EXPECT_FALSE(Box3f({{0, 0, 0}, {0.5f, 0.5f, 0.5f}}).contains(outer));
}

TEST(Box, EmptyBoxLiesInsideAnyBoxAndHoldsNone) {
    const Box3f empty;
    EXPECT_TRUE(empty.empty());
    EXPECT_TRUE(Box3f({{0, 0, 0}, {1, 1, 1}}).contains(empty));
    EXPECT_FALSE(empty.contains(Box3f{{0, 0, 0}, {0, 0, 0}}));
    EXPECT_FALSE(empty.contains(Vec3f(0.0f)));
}

}  // namespace
}  // namespace lancer
