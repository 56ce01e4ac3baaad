// core/parallel.hpp's oneTBB backend, the one lancer_core is built with when TBB is found.
#define LANCER_HAS_TBB 1
#include "parallel_checks.hpp"

namespace lancer::testing {
namespace {

TEST(ParallelTbb, VisitsEveryIndexOnce) {
    check_every_index_once();
}
TEST(ParallelTbb, ChunksTileTheRange) {
    check_chunks_tile_the_range(true);
}
TEST(ParallelTbb, BlocksAreFixed) {
    check_blocks_are_fixed();
}
TEST(ParallelTbb, ReduceMergesEveryChunk) {
    check_reduce_merges_every_chunk();
}
TEST(ParallelTbb, InvokeRunsBoth) {
    check_invoke_runs_both();
}
TEST(ParallelTbb, WithThreadsRunsItsBody) {
    check_with_threads_runs_its_body();
}
TEST(ParallelTbb, Sorts) {
    check_sort();
}
TEST(ParallelTbb, PerThreadValuesAreEachThreadsOwn) {
    check_per_thread_values_are_each_threads_own();
}

}  // namespace
}  // namespace lancer::testing
