// write_exr: read back with OpenEXR, linear half values checked (no clamping, no sRGB encoding).
#include <ImfRgbaFile.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "lancer/render.hpp"

namespace lancer {
namespace {

std::filesystem::path temporary_exr(const std::string& name) {
    const testing::TestInfo* test = testing::UnitTest::GetInstance()->current_test_info();
    return std::filesystem::temp_directory_path() /
           (std::string("lancer_") + test->test_suite_name() + "_" + test->name() + "_" + name + ".exr");
}

TEST(ExrWriter, WritesLinearHalfRgb) {
    Image image(3, 2);
    image.at(0, 0) = {0.0f, 0.5f, 1.0f};
    image.at(2, 0) = {2.5f, 100.0f, 0.001f};  // beyond 1: HDR values are kept
    image.at(1, 1) = {0.25f, 0.125f, 0.0625f};
    const auto file = temporary_exr("out");
    write_exr(image, file);

    Imf::RgbaInputFile in(file.string().c_str());
    const Imath::Box2i window = in.dataWindow();
    const int width = window.max.x - window.min.x + 1, height = window.max.y - window.min.y + 1;
    ASSERT_EQ(width, 3);
    ASSERT_EQ(height, 2);
    EXPECT_EQ(in.channels(), Imf::WRITE_RGB);
    std::vector<Imf::Rgba> pixels(6);
    in.setFrameBuffer(pixels.data(), 1, 3);
    in.readPixels(window.min.y, window.max.y);
    for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 3; ++x) {
            const Imf::Rgba& p = pixels[static_cast<std::size_t>(y * 3 + x)];
            const Vec3f expected = image.at(x, y);
            EXPECT_EQ(float(p.r), float(half(expected.x))) << x << ", " << y;
            EXPECT_EQ(float(p.g), float(half(expected.y))) << x << ", " << y;
            EXPECT_EQ(float(p.b), float(half(expected.z))) << x << ", " << y;
        }
    }
    std::filesystem::remove(file);
}

TEST(ExrWriter, FailureNamesThePath) {
    Image image(2, 2);
    const std::filesystem::path file = "/nonexistent-lancer-dir/out.exr";
    try {
        write_exr(image, file);
        FAIL() << "expected an exception";
    } catch (const std::runtime_error& error) {
        EXPECT_NE(std::string(error.what()).find(file.string()), std::string::npos) << error.what();
    }
    EXPECT_FALSE(std::filesystem::exists(file));
}

}  // namespace
}  // namespace lancer
