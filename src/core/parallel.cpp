#include "lancer/parallel.hpp"

#include <stdexcept>

#include "core/parallel.hpp"

namespace lancer {

void parallel_for(std::size_t count, std::size_t block, int threads,
                  const std::function<void(std::size_t first, std::size_t last)>& body) {
    if (block == 0) throw std::invalid_argument("parallel_for: a block of zero indices");
    parallel::with_threads(threads, [&] { parallel::for_each_block(count, block, body); });
}

void run_with_threads(int threads, const std::function<void()>& work) {
    parallel::with_threads(threads, work);
}

}  // namespace lancer
