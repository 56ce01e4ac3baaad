// Parallel loops for code built on lancer's public API (the command line, the Python module), so that it
// needs no oneTBB of its own: over oneTBB where lancer was built with it, serially otherwise, through the
// same backend as the library's builds (src/core/parallel.hpp).
#pragma once

#include <cstddef>
#include <functional>

namespace lancer {

// body(first, last) for each block [first, last) of `block` consecutive indices of [0, count) (the last one
// shorter), a block a task, on at most `threads` threads; 0 or negative: those of the run_with_threads the
// caller runs in, all hardware threads outside any. The blocks start at multiples of `block` whatever the
// threads. A count above the CPUs this process may run on counts as that many (oneTBB would use no more,
// and would warn on stderr). The first exception a body throws reaches the caller once the loop has stopped.
// Throws std::invalid_argument for a zero `block`.
void parallel_for(std::size_t count, std::size_t block, int threads,
                  const std::function<void(std::size_t first, std::size_t last)>& body);

// work() with every parallel loop it starts (parallel_for, intersect_parallel, a World's build or update) on
// at most `threads` threads, clamped as parallel_for's; 0 or negative: as parallel_for. What work() throws
// reaches the caller.
void run_with_threads(int threads, const std::function<void()>& work);

}  // namespace lancer
