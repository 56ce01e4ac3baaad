// The lock of a scene that Python threads query at once (docs/python.md, "Threads"): shared by the queries,
// which trace without the GIL, and held alone by whatever changes the scene or builds on it. Taken with the
// GIL released. A writer waits in the turnstile, which new readers pass through, so that a stream of queries
// from other threads cannot starve it.
#pragma once

#include <mutex>
#include <shared_mutex>

namespace lancer::python {

class SceneLock {
  public:
    [[nodiscard]] std::shared_lock<std::shared_mutex> reading() {
        const std::lock_guard turn(turnstile_);
        return std::shared_lock(mutex_);
    }
    [[nodiscard]] std::unique_lock<std::shared_mutex> writing() {
        const std::lock_guard turn(turnstile_);
        return std::unique_lock(mutex_);
    }
    // A shared lock under which ready() holds: prepare() makes it hold, run under the exclusive lock by the
    // first query that finds it false (the queries that find it false together wait for it, then read).
    template <class Ready, class Prepare>
    [[nodiscard]] std::shared_lock<std::shared_mutex> prepared(Ready&& ready, Prepare&& prepare) {
        // Readers cannot turn their lock into a writer's, so a query that finds something missing lets go and
        // builds it under the exclusive lock; a change may come in between, hence the loop.
        for (;;) {
            std::shared_lock lock = reading();
            if (ready()) return lock;
            lock.unlock();
            const std::unique_lock exclusive = writing();
            prepare();
        }
    }

  private:
    std::shared_mutex mutex_;
    std::mutex turnstile_;
};

}  // namespace lancer::python
