// The parallel loops of the builds, in one place: over oneTBB where lancer_core is built with it
// (LANCER_HAS_TBB), the same loops run serially otherwise, so that the traversal core needs nothing beyond
// the standard library. Callers split their work into fixed blocks where the result depends on the order,
// so a build gives the same structure with any thread count, and without TBB.
#pragma once

#include <algorithm>
#include <cstddef>
#include <utility>

#if LANCER_HAS_TBB
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>
#endif

namespace lancer::parallel {

// Each backend in its own inline namespace, so that translation units built with and without TBB (the
// library and a test) never see two definitions of one function.
#if LANCER_HAS_TBB
inline namespace tbb_backend {

// body(i) for every i in [begin, end).
template <class Body>
void for_each_index(std::size_t begin, std::size_t end, Body&& body) {
    tbb::parallel_for(begin, end, body);
}

// body(from, to) over consecutive chunks of [begin, end), each of at least `grain` indices unless it is the
// last.
template <class Body>
void for_each_chunk(std::size_t begin, std::size_t end, std::size_t grain, Body&& body) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(begin, end, grain),
        [&](const tbb::blocked_range<std::size_t>& range) { body(range.begin(), range.end()); });
}

// body(from, to) for each block of `block` consecutive indices of [0, count) (the last one shorter), a block
// a task: the blocks start at multiples of `block` whatever the threads, and a task never runs two of them.
template <class Body>
void for_each_block(std::size_t count, std::size_t block, Body&& body) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, (count + block - 1) / block, 1),
        [&](const tbb::blocked_range<std::size_t>& blocks) {
            for (std::size_t b = blocks.begin(); b < blocks.end(); ++b)
                body(b * block, std::min(count, (b + 1) * block));
        },
        tbb::simple_partitioner());
}

// accumulate(from, to, value) over chunks of [begin, end), each starting from `identity`, the chunks'
// values merged by combine(a, b). For an exact result whatever the chunks, combine must be associative and
// exact (counts, box extents).
template <class T, class Accumulate, class Combine>
[[nodiscard]] T reduce(std::size_t begin, std::size_t end, std::size_t grain, const T& identity,
                       Accumulate&& accumulate, Combine&& combine) {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(begin, end, grain), identity,
        [&](const tbb::blocked_range<std::size_t>& range, T value) {
            return accumulate(range.begin(), range.end(), std::move(value));
        },
        combine);
}

// first() and second(), concurrently.
template <class First, class Second>
void invoke(First&& first, Second&& second) {
    tbb::parallel_invoke(std::forward<First>(first), std::forward<Second>(second));
}

// body() with its loops on at most `threads` threads; 0: those of the arena the caller runs in (all of them
// outside any).
template <class Body>
void with_threads(int threads, Body&& body) {
    if (threads <= 0) {
        body();
        return;
    }
    tbb::task_arena arena(threads);
    arena.execute(body);
}

template <class Iterator>
void sort(Iterator first, Iterator last) {
    tbb::parallel_sort(first, last);
}

// One T per thread, made on a thread's first local() call.
template <class T>
class PerThread {
  public:
    [[nodiscard]] T& local() { return values_.local(); }

  private:
    tbb::enumerable_thread_specific<T> values_;
};

// Whether the loop this task runs in is being cancelled: a sibling task threw (std::bad_alloc past
// --max-memory), and TBB rethrows it once the outermost loop returns.
[[nodiscard]] inline bool cancelling() {
    return tbb::is_current_task_group_canceling();
}

}  // namespace tbb_backend
#else
inline namespace serial_backend {

template <class Body>
void for_each_index(std::size_t begin, std::size_t end, Body&& body) {
    for (std::size_t i = begin; i < end; ++i)
        body(i);
}

template <class Body>
void for_each_chunk(std::size_t begin, std::size_t end, std::size_t /*grain*/, Body&& body) {
    if (begin < end) body(begin, end);
}

template <class Body>
void for_each_block(std::size_t count, std::size_t block, Body&& body) {
    for (std::size_t from = 0; from < count; from += block)
        body(from, std::min(count, from + block));
}

template <class T, class Accumulate, class Combine>
[[nodiscard]] T reduce(std::size_t begin, std::size_t end, std::size_t /*grain*/, const T& identity,
                       Accumulate&& accumulate, Combine&& /*combine*/) {
    return accumulate(begin, end, T(identity));
}

template <class First, class Second>
void invoke(First&& first, Second&& second) {
    first();
    second();
}

template <class Body>
void with_threads(int /*threads*/, Body&& body) {
    body();
}

template <class Iterator>
void sort(Iterator first, Iterator last) {
    std::sort(first, last);
}

template <class T>
class PerThread {
  public:
    [[nodiscard]] T& local() { return value_; }

  private:
    T value_;
};

[[nodiscard]] inline bool cancelling() {
    return false;
}

}  // namespace serial_backend
#endif

}  // namespace lancer::parallel
