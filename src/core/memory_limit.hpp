// The counter behind include/lancer/memory_limit.hpp, for the allocators that feed it: the replaced global
// operator new (memory_limit_new.cpp) and Embree's device memory monitor (src/accel/embree.cpp).
#pragma once

#include <cstddef>

namespace lancer::memory {

// Whether `bytes` more fit under the limit (always true without one). Only a check: the caller counts what it
// then allocates with add().
[[nodiscard]] bool fits(std::size_t bytes);
void add(std::size_t bytes);
void subtract(std::size_t bytes);

}  // namespace lancer::memory
