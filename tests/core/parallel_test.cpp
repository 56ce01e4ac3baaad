// core/parallel.hpp's serial backend: the tests are built without LANCER_HAS_TBB.
#include "parallel_checks.hpp"

#if LANCER_HAS_TBB
#error "parallel_test.cpp checks the serial backend"
#endif

namespace lancer::testing {
namespace {

TEST(ParallelSerial, VisitsEveryIndexOnce) {
    check_every_index_once();
}
TEST(ParallelSerial, ChunksTileTheRange) {
    check_chunks_tile_the_range(false);
}
TEST(ParallelSerial, BlocksAreFixed) {
    check_blocks_are_fixed();
}
TEST(ParallelSerial, ReduceMergesEveryChunk) {
    check_reduce_merges_every_chunk();
}
TEST(ParallelSerial, InvokeRunsBoth) {
    check_invoke_runs_both();
}
TEST(ParallelSerial, WithThreadsRunsItsBody) {
    check_with_threads_runs_its_body();
}
TEST(ParallelSerial, Sorts) {
    check_sort();
}
TEST(ParallelSerial, PerThreadValuesAreEachThreadsOwn) {
    check_per_thread_values_are_each_threads_own();
}

}  // namespace
}  // namespace lancer::testing
