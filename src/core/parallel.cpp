#include "lancer/parallel.hpp"

#include <algorithm>
#include <stdexcept>

#include "core/parallel.hpp"

#if LANCER_HAS_TBB
#include <tbb/info.h>
#endif

namespace lancer {

namespace {

// A thread count no wider than the CPUs this process may run on: oneTBB would not use more, and says so on
// stderr, once a process, whoever asked (a Python user's nthreads=1000 among them).
int within_machine(int threads) {
#if LANCER_HAS_TBB
    return std::min(threads, tbb::info::default_concurrency());
#else
    return threads;
#endif
}

}  // namespace

void parallel_for(std::size_t count, std::size_t block, int threads,
                  const std::function<void(std::size_t first, std::size_t last)>& body) {
    if (block == 0) throw std::invalid_argument("parallel_for: a block of zero indices");
    parallel::with_threads(within_machine(threads), [&] { parallel::for_each_block(count, block, body); });
}

void run_with_threads(int threads, const std::function<void()>& work) {
    parallel::with_threads(within_machine(threads), work);
}

}  // namespace lancer
