#include "render/progress.hpp"

#include <cstdio>
#include <utility>

namespace lancer {
namespace {

// Ten updates a second: smooth to the eye, negligible beside the work of a tile.
constexpr std::chrono::milliseconds kPrintInterval{100};

}  // namespace

std::string progress_line(std::string_view label, std::string_view unit, std::uint64_t done,
                          std::uint64_t total, double elapsed_s, bool show_eta) {
    const auto percent = total == 0 ? 100ull : static_cast<unsigned long long>(done * 100 / total);
    char counts[128];
    std::snprintf(counts, sizeof counts, " %3llu%% (%llu/%llu ", percent,
                  static_cast<unsigned long long>(done), static_cast<unsigned long long>(total));
    char times[96];
    if (show_eta && done > 0) {
        const double remaining = static_cast<double>(total > done ? total - done : 0);
        const double eta_s = elapsed_s * remaining / static_cast<double>(done);
        std::snprintf(times, sizeof times, ") %.1f s, ETA %.1f s", elapsed_s, eta_s);
    } else {
        std::snprintf(times, sizeof times, ") %.1f s", elapsed_s);
    }
    std::string line(label);
    line += counts;
    line += unit;
    line += times;
    return line;
}

ProgressReporter::ProgressReporter(std::string label, std::uint64_t total, std::string unit, bool enabled)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      enabled_(enabled),
      start_(Clock::now()),
      next_print_((start_ + kPrintInterval).time_since_epoch().count()) {}

ProgressReporter::~ProgressReporter() {
    finish();
}

void ProgressReporter::advance(std::uint64_t units) {
    if (!enabled_) return;
    done_.fetch_add(units, std::memory_order_relaxed);
    const Clock::time_point now = Clock::now();
    if (now.time_since_epoch().count() < next_print_.load(std::memory_order_relaxed)) return;
    // A thread that finds another printing skips the print rather than wait: the next advance will do it.
    std::unique_lock lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock() || finished_) return;
    next_print_.store((now + kPrintInterval).time_since_epoch().count(), std::memory_order_relaxed);
    print(false);
}

void ProgressReporter::finish() {
    if (!enabled_) return;
    const std::scoped_lock lock(mutex_);
    if (finished_) return;
    finished_ = true;
    print(true);
}

void ProgressReporter::print(bool final_line) {
    const std::chrono::duration<double> elapsed = Clock::now() - start_;
    std::string line = progress_line(label_, unit_, done_.load(std::memory_order_relaxed), total_,
                                     elapsed.count(), !final_line);
    const std::size_t length = line.size();
    if (length < printed_length_) line.append(printed_length_ - length, ' ');
    printed_length_ = length;
    std::fprintf(stderr, "\r%s%s", line.c_str(), final_line ? "\n" : "");
    std::fflush(stderr);
}

}  // namespace lancer
