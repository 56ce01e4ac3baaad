// The one message every rank sends rank 0 at the end of a distributed frame (docs/distributed.md): its
// part of the frame, or why it has none, as bytes, with the writer and reader that make and read them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "lancer/render.hpp"

namespace lancer::cli {

// Bytes appended to, and read back from, a buffer sent in one message. Both ends run the same binary, so
// values go as their bytes.
class Writer {
  public:
    template <class T>
    void put(const T& value) {
        static_assert(std::is_trivially_copyable_v<T>);
        const auto* bytes = reinterpret_cast<const std::byte*>(&value);
        buffer_.insert(buffer_.end(), bytes, bytes + sizeof(T));
    }
    template <class T>
    void put_all(std::span<const T> values) {
        static_assert(std::is_trivially_copyable_v<T>);
        put(static_cast<std::uint64_t>(values.size()));
        const auto* bytes = reinterpret_cast<const std::byte*>(values.data());
        buffer_.insert(buffer_.end(), bytes, bytes + values.size_bytes());
    }
    [[nodiscard]] std::vector<std::byte>& bytes() { return buffer_; }

  private:
    std::vector<std::byte> buffer_;
};

class Reader {
  public:
    explicit Reader(std::span<const std::byte> bytes) : bytes_(bytes) {}
    template <class T>
    T get() {
        T value;
        take(&value, sizeof(T));
        return value;
    }
    template <class T>
    std::vector<T> get_all() {
        const auto count = get<std::uint64_t>();
        if (count > (bytes_.size() - offset_) / sizeof(T))
            throw std::runtime_error("MPI: a message is cut short");
        std::vector<T> values(static_cast<std::size_t>(count));
        take(values.data(), values.size() * sizeof(T));
        return values;
    }

  private:
    void take(void* out, std::size_t size) {
        if (size > bytes_.size() - offset_) throw std::runtime_error("MPI: a message is cut short");
        std::memcpy(out, bytes_.data() + offset_, size);
        offset_ += size;
    }
    std::span<const std::byte> bytes_;
    std::size_t offset_ = 0;
};

// A rank's part of the frame (a leading 1, then its fields), or when `part` is null its failure (a leading
// 0, the exit code, the message).
[[nodiscard]] std::vector<std::byte> serialise(const FramePart* part, const std::string& failure,
                                               int exit_code);

// serialise's inverse for a part (the leading 1 already read). Throws std::runtime_error for a message cut
// short.
[[nodiscard]] FramePart deserialise_part(Reader& reader);

}  // namespace lancer::cli
