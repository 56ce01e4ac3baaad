// The largest single request made to the global operator new since the last reset: lets a test prove that a
// loader refused a huge header count before allocating for it. allocation_probe.cpp replaces operator new
// in the test executable to record it.
#pragma once

#include <cstddef>

namespace lancer::test {

void reset_largest_allocation();
[[nodiscard]] std::size_t largest_allocation();

}  // namespace lancer::test
