// Readable GoogleTest failure messages for Vec3f (found by argument-dependent lookup in namespace lancer).
#pragma once

#include <ostream>

#include "lancer/vec.hpp"

namespace lancer {

inline void PrintTo(const Vec3f& v, std::ostream* os) {
    *os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
}

}  // namespace lancer
