// 8-bit sRGB PNG through libpng. libpng reports errors by longjmp; the jump is confined to write_rows(),
// whose frame holds only plain C objects, so no destructor is ever skipped.
#include <png.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "lancer/render.hpp"

namespace lancer {
namespace {

// Where the error callback leaves libpng's message before jumping back to write_rows().
struct PngError {
    char message[256];
};

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
    auto* error = static_cast<PngError*>(png_get_error_ptr(png));
    std::snprintf(error->message, sizeof error->message, "%s", message);
    png_longjmp(png, 1);
}

// Warnings (an unusual but valid request) do not stop the write and must not reach stderr from a library.
void on_png_warning(png_structp, png_const_charp) {}

// Writes `rows` (height pointers to width * 3 bytes) to `file`. Returns false with `error` filled on failure.
bool write_rows(std::FILE* file, png_uint_32 width, png_uint_32 height, png_bytep* rows, PngError* error) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, error, on_png_error, on_png_warning);
    if (png == nullptr) {
        std::snprintf(error->message, sizeof error->message, "libpng could not allocate its write state");
        return false;
    }
    png_infop info = png_create_info_struct(png);
    if (info == nullptr) {
        png_destroy_write_struct(&png, nullptr);
        std::snprintf(error->message, sizeof error->message, "libpng could not allocate its info state");
        return false;
    }
    // png and info are not modified after this point, so they keep their values across the longjmp.
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return false;
    }
    png_init_io(png, file);
    png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    // The sRGB chunk (with its gAMA and cHRM fallbacks) tells viewers which encoding the bytes are in.
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    png_write_image(png, rows);
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    return true;
}

// The sRGB transfer function (IEC 61966-2-1) of a linear value clamped to [0, 1], rounded to 8 bits.
// NaN counts as black.
std::uint8_t encode_srgb(float linear) {
    const double c = linear > 0.0f ? std::min(static_cast<double>(linear), 1.0) : 0.0;
    const double encoded = c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
    return static_cast<std::uint8_t>(std::lround(encoded * 255.0));
}

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& reason) {
    throw std::runtime_error("cannot write PNG '" + file.string() + "': " + reason);
}

struct FileCloser {
    void operator()(std::FILE* file) const { std::fclose(file); }
};

}  // namespace

void write_png(const Image& image, const std::filesystem::path& file) {
    if (image.width <= 0 || image.height <= 0 ||
        image.pixels.size() !=
            static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height)) {
        fail(file, "the image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                       " with " + std::to_string(image.pixels.size()) + " pixels");
    }
    const auto row_bytes = static_cast<std::size_t>(image.width) * 3;
    std::vector<png_byte> bytes(row_bytes * static_cast<std::size_t>(image.height));
    for (std::size_t i = 0; i < image.pixels.size(); ++i) {
        bytes[3 * i] = encode_srgb(image.pixels[i].x);
        bytes[3 * i + 1] = encode_srgb(image.pixels[i].y);
        bytes[3 * i + 2] = encode_srgb(image.pixels[i].z);
    }
    std::vector<png_bytep> rows(static_cast<std::size_t>(image.height));
    for (std::size_t y = 0; y < rows.size(); ++y)
        rows[y] = bytes.data() + y * row_bytes;

    std::unique_ptr<std::FILE, FileCloser> out(std::fopen(file.string().c_str(), "wb"));
    if (!out) fail(file, "cannot open: " + std::generic_category().message(errno));
    PngError error{};
    const bool written = write_rows(out.get(), static_cast<png_uint_32>(image.width),
                                    static_cast<png_uint_32>(image.height), rows.data(), &error);
    // fclose flushes the last buffered bytes: a full disk shows up only here.
    const bool closed = std::fclose(out.release()) == 0;
    if (!written || !closed) {
        const std::string reason = written ? "closing failed: " + std::generic_category().message(errno)
                                           : std::string(error.message);
        std::error_code ignored;
        std::filesystem::remove(file, ignored);  // never leave a truncated PNG behind
        fail(file, reason);
    }
}

}  // namespace lancer
