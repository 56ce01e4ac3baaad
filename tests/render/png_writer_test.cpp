// write_png: read back with libpng's simplified API, sRGB values checked; failures name the path.
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "lancer/render.hpp"

namespace lancer {
namespace {

std::filesystem::path temporary_png(const std::string& name) {
    const testing::TestInfo* test = testing::UnitTest::GetInstance()->current_test_info();
    return std::filesystem::temp_directory_path() /
           (std::string("lancer_") + test->test_suite_name() + "_" + test->name() + "_" + name + ".png");
}

struct DecodedPng {
    png_uint_32 width = 0, height = 0, format = 0;
    std::vector<png_byte> rgb;
};

DecodedPng read_png(const std::filesystem::path& file) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, file.c_str())) {
        ADD_FAILURE() << "libpng cannot read " << file << ": " << image.message;
        return {};
    }
    DecodedPng decoded{image.width, image.height, image.format, {}};
    image.format = PNG_FORMAT_RGB;
    decoded.rgb.resize(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, decoded.rgb.data(), 0, nullptr)) {
        ADD_FAILURE() << "libpng cannot decode " << file << ": " << image.message;
    }
    return decoded;
}

TEST(WritePng, RoundTripEncodesSrgb) {
    Image image(3, 2);
    image.at(0, 0) = {0.0f, 1.0f, 0.5f};
    image.at(1, 0) = {-1.0f, 2.0f, std::numeric_limits<float>::quiet_NaN()};  // clamped; NaN is black
    image.at(2, 0) = {0.002f, 0.2f, 0.0031308f};                              // linear toe, curve, the knee
    image.at(0, 1) = {1.0f, 0.0f, 0.0f};
    image.at(1, 1) = {0.0f, 1.0f, 0.0f};
    image.at(2, 1) = {0.0f, 0.0f, 1.0f};
    const std::filesystem::path file = temporary_png("roundtrip");
    write_png(image, file);

    const DecodedPng decoded = read_png(file);
    std::filesystem::remove(file);
    EXPECT_EQ(decoded.width, 3u);
    EXPECT_EQ(decoded.height, 2u);
    EXPECT_EQ(decoded.format, static_cast<png_uint_32>(PNG_FORMAT_RGB));  // 8-bit colour, no alpha
    const std::vector<png_byte> expected = {
        0,   255, 188,  // 0.5 linear: 1.055 * 0.5^(1/2.4) - 0.055 = 0.7354 -> 187.5 -> 188
        0,   255, 0,    //
        7,   124, 10,   // 12.92 * 0.002 * 255 = 6.6; 0.2 -> 0.4845 -> 123.6; 12.92 * 0.0031308 * 255 = 10.3
        255, 0,   0,    // rows top first
        0,   255, 0,    //
        0,   0,   255,  //
    };
    EXPECT_EQ(decoded.rgb, expected);
}

TEST(WritePng, MissingDirectoryThrowsWithThePath) {
    const std::filesystem::path file =
        std::filesystem::temp_directory_path() / "lancer_no_such_directory_b0c9" / "image.png";
    try {
        write_png(Image(2, 2), file);
        FAIL() << "write_png succeeded into a missing directory";
    } catch (const std::runtime_error& error) {
        const std::string message = error.what();
        EXPECT_NE(message.find(file.string()), std::string::npos) << message;
        EXPECT_NE(message.find("No such file or directory"), std::string::npos) << message;
    }
}

TEST(WritePng, EmptyImageThrowsAndWritesNothing) {
    const std::filesystem::path file = temporary_png("empty");
    EXPECT_THROW(write_png(Image(0, 0), file), std::runtime_error);
    EXPECT_FALSE(std::filesystem::exists(file));
}

TEST(WritePng, ImageWithTooFewPixelsThrows) {
    Image image(4, 4);
    image.pixels.resize(5);
    const std::filesystem::path file = temporary_png("short");
    EXPECT_THROW(write_png(image, file), std::runtime_error);
    EXPECT_FALSE(std::filesystem::exists(file));
}

}  // namespace
}  // namespace lancer
