// The front end shared by the hand-written readers (OFF, DSC, NFF): whitespace-separated tokens with their
// line numbers, '#' comments, strict numbers, and the checks that keep hostile input from crashing the
// loader or making it allocate blindly. Every failure is a LoadError naming the file and the line.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "lancer/vec.hpp"

namespace lancer {

struct Token {
    std::string_view text;
    std::size_t line = 0;
};

// LoadError (line 0) unless `file` is a regular file that can be opened for reading.
void check_readable(const std::filesystem::path& file);

// The whole file as bytes; LoadError (line 0) when it is missing, not a regular file or unreadable.
[[nodiscard]] std::string read_file(const std::filesystem::path& file);

// A token as error messages show it: quoted, at most a few dozen characters, non-printable bytes escaped
// (binary garbage must not turn the message into garbage).
[[nodiscard]] std::string quote_token(std::string_view text);

// "40 faces, got 39": how many records were announced and how many came.
[[nodiscard]] std::string count_message(std::uint64_t expected, std::string_view plural_what,
                                        std::uint64_t got);

// An image side past this is a corrupt header, not a picture anyone renders.
constexpr std::int64_t max_image_side = 1 << 16;

class TextReader {
  public:
    // Reads the file (LoadError when it cannot).
    explicit TextReader(const std::filesystem::path& file);
    // Reads `text` as if it were the content of `file` (the name is only used in messages).
    TextReader(std::filesystem::path file, std::string text);

    // Tokens are views into the text the reader owns: it must stay where it is.
    TextReader(const TextReader&) = delete;
    TextReader& operator=(const TextReader&) = delete;

    // The next token, skipping whitespace and comments ('#' to the end of the line); nullopt at the end.
    [[nodiscard]] std::optional<Token> next();
    // The token next() would return, left in place.
    [[nodiscard]] std::optional<Token> peek();
    // Whether another token follows on the current line.
    [[nodiscard]] bool line_has_more_tokens() const;
    // Drops what is left of the current line: the extra columns (colours, normals) of OFF records.
    void skip_rest_of_line();
    // The bytes after the end of the current line: the binary body that follows a PLY header.
    [[nodiscard]] std::string_view bytes_after_line() const;

    // The next token, or LoadError "unexpected end of file: expected WHAT".
    [[nodiscard]] Token expect_token(std::string_view what);
    // Typed reads: `what` names the expected thing in the message ("expected WHAT, got 'abc'"); `where`,
    // when given, receives the token, for later messages about the value. A number is the whole token
    // (no trailing garbage); floats must be finite; a count is a non-negative integer.
    [[nodiscard]] float read_float(std::string_view what, Token* where = nullptr);
    [[nodiscard]] Vec3f read_vec3(std::string_view what);
    [[nodiscard]] std::int64_t read_integer(std::string_view what, Token* where = nullptr);
    [[nodiscard]] std::uint64_t read_count(std::string_view what, Token* where = nullptr);
    // An image width or height, in [1, max_image_side].
    [[nodiscard]] int read_image_side(std::string_view what);
    // Whether the next token reads as a number: optional trailing values such as NFF's light colour.
    [[nodiscard]] bool next_is_number();
    // The next token must be `keyword`.
    void expect_keyword(std::string_view keyword);

    // Fails unless `count` records of at least `min_chars` characters each (their separator included) fit
    // in `budget` bytes: a header count is checked against the size of the file before anything is
    // reserved for it, so that "1000000000000 vertices" is a clean error, not a bad_alloc or a long wait.
    void check_fits(std::uint64_t count, std::size_t min_chars, std::size_t budget, const Token& where,
                    std::string_view plural_what) const;

    // Bytes after the cursor, plus one: the last record of a file needs no separator after it.
    [[nodiscard]] std::size_t byte_budget() const { return text_.size() - pos_ + 1; }
    // The last line of the file: where "unexpected end of file" is reported.
    [[nodiscard]] std::size_t last_line() const { return last_line_; }
    [[nodiscard]] const std::filesystem::path& file() const { return file_; }

    [[noreturn]] void fail(std::size_t line, const std::string& message) const;
    [[noreturn]] void fail_at_end(std::string_view what) const;

  private:
    void skip_blanks_and_comments();

    std::filesystem::path file_;
    std::string text_;
    std::size_t pos_ = 0;
    std::size_t line_ = 1;
    std::size_t last_line_ = 1;
};

}  // namespace lancer
