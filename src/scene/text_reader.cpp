#include "scene/text_reader.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <system_error>
#include <utility>

#include "lancer/load_scene.hpp"

namespace lancer {

namespace {

bool is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}
bool ends_token(char c) {
    return is_blank(c) || c == '#';
}

enum class NumberStatus { ok, malformed, not_finite, out_of_range };

// from_chars does not take the '+' that some writers put in front of positive numbers.
std::string_view without_plus(std::string_view text) {
    if (text.size() > 1 && text[0] == '+' && text[1] != '-' && text[1] != '+') text.remove_prefix(1);
    return text;
}

NumberStatus parse_float(std::string_view text, float& value) {
    text = without_plus(text);
    const char* const end = text.data() + text.size();
    const auto [stop, error] = std::from_chars(text.data(), end, value);
    if (error == std::errc::invalid_argument || stop != end) return NumberStatus::malformed;
    if (error == std::errc::result_out_of_range) {
        // Too large for a float, or too small: a value like 1e-50 written by a double-precision tool is
        // zero to us, not an error.
        double wide = 0.0;
        const auto [wide_stop, wide_error] = std::from_chars(text.data(), end, wide);
        if (wide_error != std::errc() || wide_stop != end || std::fabs(wide) >= 1.0)
            return NumberStatus::out_of_range;
        value = static_cast<float>(wide);
    }
    return std::isfinite(value) ? NumberStatus::ok : NumberStatus::not_finite;
}

NumberStatus parse_integer(std::string_view text, std::int64_t& value) {
    text = without_plus(text);
    const char* const end = text.data() + text.size();
    const auto [stop, error] = std::from_chars(text.data(), end, value);
    if (error == std::errc::invalid_argument || stop != end) return NumberStatus::malformed;
    return error == std::errc::result_out_of_range ? NumberStatus::out_of_range : NumberStatus::ok;
}

std::string bad_number_message(std::string_view what, std::string_view token, NumberStatus status) {
    std::string message = "expected " + std::string(what) + ", got " + quote_token(token);
    if (status == NumberStatus::not_finite) message += " (not a finite number)";
    if (status == NumberStatus::out_of_range) message += " (out of range)";
    return message;
}

std::size_t count_lines(std::string_view text) {
    if (text.empty()) return 1;
    std::size_t lines = 0;
    for (char c : text)
        lines += c == '\n' ? 1 : 0;
    return text.back() == '\n' ? lines : lines + 1;
}

}  // namespace

void check_readable(const std::filesystem::path& file) {
    std::error_code error;
    const auto status = std::filesystem::status(file, error);
    if (!std::filesystem::exists(status)) throw LoadError(file, 0, "cannot open file: no such file");
    if (!std::filesystem::is_regular_file(status))
        throw LoadError(file, 0, "cannot open file: not a regular file");
    if (!std::ifstream(file, std::ios::binary)) {
        throw LoadError(file, 0, std::string("cannot open file: ") + std::strerror(errno));
    }
}

std::string read_file(const std::filesystem::path& file) {
    check_readable(file);
    std::ifstream stream(file, std::ios::binary);
    // Grow with the bytes actually read rather than trusting a size taken before the read.
    std::string text;
    char buffer[1 << 16];
    while (stream.read(buffer, sizeof buffer) || stream.gcount() > 0) {
        text.append(buffer, static_cast<std::size_t>(stream.gcount()));
    }
    if (stream.bad()) throw LoadError(file, 0, "cannot read file");
    return text;
}

std::string quote_token(std::string_view text) {
    constexpr std::size_t max_shown = 40;
    std::string quoted = "'";
    for (std::size_t i = 0; i < text.size() && i < max_shown; ++i) {
        const auto byte = static_cast<unsigned char>(text[i]);
        if (byte >= 0x20 && byte < 0x7f) {
            quoted += static_cast<char>(byte);
        } else {
            char escaped[8];
            std::snprintf(escaped, sizeof escaped, "\\x%02x", static_cast<unsigned>(byte));
            quoted += escaped;
        }
    }
    if (text.size() > max_shown) quoted += "...";
    return quoted + "'";
}

std::string count_message(std::uint64_t expected, std::string_view plural_what, std::uint64_t got) {
    return std::to_string(expected) + " " + std::string(plural_what) + ", got " + std::to_string(got);
}

TextReader::TextReader(const std::filesystem::path& file) : TextReader(file, read_file(file)) {}

TextReader::TextReader(std::filesystem::path file, std::string text)
    : file_(std::move(file)), text_(std::move(text)), last_line_(count_lines(text_)) {}

void TextReader::skip_blanks_and_comments() {
    while (pos_ < text_.size()) {
        const char c = text_[pos_];
        if (c == '\n') {
            ++line_, ++pos_;
        } else if (is_blank(c)) {
            ++pos_;
        } else if (c == '#') {
            skip_rest_of_line();
        } else {
            return;
        }
    }
}

std::optional<Token> TextReader::next() {
    skip_blanks_and_comments();
    if (pos_ == text_.size()) return std::nullopt;
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !ends_token(text_[pos_]))
        ++pos_;
    return Token{std::string_view(text_).substr(start, pos_ - start), line_};
}

std::optional<Token> TextReader::peek() {
    const std::size_t saved_pos = pos_, saved_line = line_;
    const std::optional<Token> token = next();
    pos_ = saved_pos, line_ = saved_line;
    return token;
}

bool TextReader::line_has_more_tokens() const {
    std::size_t pos = pos_;
    while (pos < text_.size() && text_[pos] != '\n' && is_blank(text_[pos]))
        ++pos;
    return pos < text_.size() && text_[pos] != '\n' && text_[pos] != '#';
}

void TextReader::skip_rest_of_line() {
    const std::size_t newline = text_.find('\n', pos_);
    pos_ = newline == std::string::npos ? text_.size() : newline;
}

std::string_view TextReader::bytes_after_line() const {
    const std::size_t newline = text_.find('\n', pos_);
    return newline == std::string::npos ? std::string_view() : std::string_view(text_).substr(newline + 1);
}

Token TextReader::expect_token(std::string_view what) {
    const std::optional<Token> token = next();
    if (!token) fail_at_end(what);
    return *token;
}

float TextReader::read_float(std::string_view what, Token* where) {
    const Token token = expect_token(what);
    float value = 0.0f;
    const NumberStatus status = parse_float(token.text, value);
    if (status != NumberStatus::ok) fail(token.line, bad_number_message(what, token.text, status));
    if (where != nullptr) *where = token;
    return value;
}

Vec3f TextReader::read_vec3(std::string_view what) {
    const float x = read_float(what);
    const float y = read_float(what);
    return {x, y, read_float(what)};
}

std::int64_t TextReader::read_integer(std::string_view what, Token* where) {
    const Token token = expect_token(what);
    std::int64_t value = 0;
    const NumberStatus status = parse_integer(token.text, value);
    if (status != NumberStatus::ok) fail(token.line, bad_number_message(what, token.text, status));
    if (where != nullptr) *where = token;
    return value;
}

std::uint64_t TextReader::read_count(std::string_view what, Token* where) {
    Token token;
    const std::int64_t value = read_integer(what, &token);
    if (value < 0)
        fail(token.line,
             "expected " + std::string(what) + ", got " + quote_token(token.text) + " (negative)");
    if (where != nullptr) *where = token;
    return static_cast<std::uint64_t>(value);
}

int TextReader::read_image_side(std::string_view what) {
    Token token;
    const std::int64_t side = read_integer(what, &token);
    if (side < 1 || side > max_image_side) {
        fail(token.line, "expected " + std::string(what) + " between 1 and " +
                             std::to_string(max_image_side) + ", got " + quote_token(token.text));
    }
    return static_cast<int>(side);
}

bool TextReader::next_is_number() {
    const std::optional<Token> token = peek();
    float value = 0.0f;
    return token && parse_float(token->text, value) != NumberStatus::malformed;
}

void TextReader::expect_keyword(std::string_view keyword) {
    const std::string what = std::string("'").append(keyword).append("'");
    const Token token = expect_token(what);
    if (token.text != keyword) fail(token.line, "expected " + what + ", got " + quote_token(token.text));
}

void TextReader::check_fits(std::uint64_t count, std::size_t min_chars, std::size_t budget,
                            const Token& where, std::string_view plural_what) const {
    const std::size_t most = budget / min_chars;
    if (count <= most) return;
    fail(where.line, "the file announces " + std::to_string(count) + " " + std::string(plural_what) +
                         ", but the rest of it can hold at most " + std::to_string(most) + " (at least " +
                         std::to_string(min_chars) + " characters each)");
}

void TextReader::fail(std::size_t line, const std::string& message) const {
    throw LoadError(file_, line, message);
}

void TextReader::fail_at_end(std::string_view what) const {
    fail(last_line_, "unexpected end of file: expected " + std::string(what));
}

}  // namespace lancer
