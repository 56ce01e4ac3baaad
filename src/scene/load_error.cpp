#include "lancer/load_scene.hpp"

#include <utility>

namespace lancer {

namespace {

// "FILE:LINE: MESSAGE", the form compilers use, so that editors can jump to the line; "FILE: MESSAGE" when
// the error is not tied to a line.
std::string located_message(const std::filesystem::path& file, std::size_t line, const std::string& message) {
    std::string text = file.string();
    if (line > 0) text.append(":").append(std::to_string(line));
    return text.append(": ").append(message);
}

}  // namespace

LoadError::LoadError(std::filesystem::path file, std::size_t line, const std::string& message)
    : std::runtime_error(located_message(file, line, message)), file_(std::move(file)), line_(line) {}

}  // namespace lancer
