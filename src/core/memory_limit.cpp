#include "core/memory_limit.hpp"

#include <algorithm>
#include <atomic>
#include <charconv>
#include <stdexcept>
#include <string>

#include "lancer/memory_limit.hpp"

namespace lancer {
namespace {

// Relaxed: the count is a budget, not a synchronisation point; an allocation racing with another may see a
// total a few requests stale, which moves the point of failure by those requests at most.
std::atomic<std::size_t> allocated{0};
std::atomic<std::size_t> limit{0};

constexpr std::string_view kSuffixes = "KMGT";

}  // namespace

namespace memory {

bool fits(std::size_t bytes) {
    const std::size_t bound = limit.load(std::memory_order_relaxed);
    return bound == 0 || bytes <= bound - std::min(bound, allocated.load(std::memory_order_relaxed));
}
void add(std::size_t bytes) {
    allocated.fetch_add(bytes, std::memory_order_relaxed);
}
void subtract(std::size_t bytes) {
    allocated.fetch_sub(bytes, std::memory_order_relaxed);
}

}  // namespace memory

std::size_t allocated_bytes() {
    return allocated.load(std::memory_order_relaxed);
}

void set_memory_limit(std::size_t bytes) {
    limit.store(bytes, std::memory_order_relaxed);
}

std::size_t memory_limit() {
    return limit.load(std::memory_order_relaxed);
}

std::size_t parse_memory_size(std::string_view text) {
    const auto reject = [&](const char* why) {
        return std::invalid_argument("expected a memory size such as 512M or 2G, got '" + std::string(text) +
                                     "' (" + why + ")");
    };
    std::size_t count = 0;
    const char* end = text.data() + text.size();
    auto [rest, error] = std::from_chars(text.data(), end, count);
    if (error == std::errc::result_out_of_range) throw reject("too large");
    if (error != std::errc{}) throw reject("not a number");
    std::string_view suffix(rest, static_cast<std::size_t>(end - rest));
    int shift = 0;
    if (!suffix.empty() && kSuffixes.find(suffix.front()) != std::string_view::npos) {
        shift = 10 * (1 + static_cast<int>(kSuffixes.find(suffix.front())));
        suffix.remove_prefix(1);
        if (suffix == "iB") suffix = {};
    }
    if (suffix == "B") suffix = {};
    if (!suffix.empty()) throw reject("unknown unit");
    if (count == 0) throw reject("zero");
    if (count > (~std::size_t{0} >> shift)) throw reject("too large");
    return count << shift;
}

std::string format_memory_size(std::size_t bytes) {
    for (int index = static_cast<int>(kSuffixes.size()) - 1; index >= 0; --index) {
        const int shift = 10 * (index + 1);
        if (bytes != 0 && bytes % (std::size_t{1} << shift) == 0)
            return std::to_string(bytes >> shift) + kSuffixes[static_cast<std::size_t>(index)];
    }
    return std::to_string(bytes) + " bytes";
}

}  // namespace lancer
