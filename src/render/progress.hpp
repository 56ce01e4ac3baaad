// A progress line on stderr for long jobs (renders, builds, benches), rewritten in place with '\r':
//   render  42% (1234/4096 tiles) 1.3 s, ETA 1.8 s
// at most ten times a second, and ended by a newline when the job finishes.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>

namespace lancer {

// One state of the line, without '\r' or padding. The percentage is rounded down, so 100% means done; the
// ETA (elapsed time scaled by the work left) is shown when `show_eta` is set and some work is done.
[[nodiscard]] std::string progress_line(std::string_view label, std::string_view unit, std::uint64_t done,
                                        std::uint64_t total, double elapsed_s, bool show_eta);

class ProgressReporter {
  public:
    // `total` units of `unit` (a plural noun: "tiles"). Disabled, every call returns at once and nothing is
    // printed, so callers keep one code path whether or not stderr is a terminal.
    ProgressReporter(std::string label, std::uint64_t total, std::string unit, bool enabled);
    // Ends the line (finish()) if the job left early, on an exception for instance.
    ~ProgressReporter();
    ProgressReporter(const ProgressReporter&) = delete;
    ProgressReporter& operator=(const ProgressReporter&) = delete;

    // Thread-safe. Reprints the line when 100 ms have passed since the last print and no other thread is
    // printing; otherwise only counts.
    void advance(std::uint64_t units = 1);
    // Prints the final state of the line and a newline; later calls and advances print nothing.
    void finish();

  private:
    using Clock = std::chrono::steady_clock;

    void print(bool final_line);  // under mutex_

    std::string label_;
    std::string unit_;
    std::uint64_t total_;
    bool enabled_;
    Clock::time_point start_;
    std::atomic<std::uint64_t> done_{0};
    std::atomic<Clock::rep> next_print_;  // in Clock ticks since the epoch
    std::mutex mutex_;                    // one printer at a time; guards the two fields below
    std::size_t printed_length_ = 0;      // of the line on screen, to blank what a shorter one leaves
    bool finished_ = false;
};

}  // namespace lancer
