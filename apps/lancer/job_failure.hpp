// What a failure on one rank tells the whole job (docs/distributed.md): the exit code every rank ends with
// and the message rank 0 prints.
#pragma once

#include <exception>
#include <string>

namespace lancer::cli {

// 2 for bad input (a file, an option) and memory, as main() gives them, a JobError's own code, 1 for the
// rest.
[[nodiscard]] int exit_code_of(const std::exception_ptr& failure);

// The failure's what(), or for memory the message --max-memory's failures give.
[[nodiscard]] std::string message_of(const std::exception_ptr& failure);

}  // namespace lancer::cli
