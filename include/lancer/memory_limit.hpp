// A bound on what loading and building may allocate (`--max-memory`), on the model of Embree's device memory
// monitor: every byte the global operator new hands out (and every byte Embree reports) is counted, and an
// allocation that would pass the limit throws std::bad_alloc before it is made.
//
// The count covers operator new only where the program links the `lancer_memory` object library (the lancer
// executable does): it replaces the global allocation functions. Elsewhere allocated_bytes() sees Embree's
// reports alone and the limit binds only them.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace lancer {

// Bytes allocated through the counted allocators and not yet freed.
[[nodiscard]] std::size_t allocated_bytes();

// 0 (the default) lifts the limit. The limit applies to the total in allocated_bytes(), what was allocated
// before the call included.
void set_memory_limit(std::size_t bytes);
[[nodiscard]] std::size_t memory_limit();

// "512M" -> 512 << 20; accepts a plain byte count or one of the suffixes K, M, G, T (powers of 1024, with an
// optional trailing B or iB). Throws std::invalid_argument quoting the text otherwise, or for zero.
[[nodiscard]] std::size_t parse_memory_size(std::string_view text);
// The inverse for messages: 536870912 -> "512M", 1000 -> "1000 bytes".
[[nodiscard]] std::string format_memory_size(std::size_t bytes);

}  // namespace lancer
