// OpenEXR output: linear RGB as half floats, no alpha (Imf::RgbaOutputFile with WRITE_RGB), the values as
// rendered, neither clamped nor encoded. OpenEXR reports errors by exceptions.
#include <ImfRgbaFile.h>

#include <exception>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "lancer/render.hpp"

namespace lancer {

void write_exr(const Image& image, const std::filesystem::path& file) {
    if (image.width <= 0 || image.height <= 0 ||
        image.pixels.size() !=
            static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height)) {
        throw std::runtime_error("cannot write EXR '" + file.string() + "': the image is " +
                                 std::to_string(image.width) + "x" + std::to_string(image.height) + " with " +
                                 std::to_string(image.pixels.size()) + " pixels");
    }
    std::vector<Imf::Rgba> pixels(image.pixels.size());
    for (std::size_t i = 0; i < pixels.size(); ++i) {
        const Vec3f& p = image.pixels[i];
        pixels[i] = Imf::Rgba(half(p.x), half(p.y), half(p.z), half(1.0f));
    }
    try {
        Imf::RgbaOutputFile out(file.string().c_str(), image.width, image.height, Imf::WRITE_RGB);
        out.setFrameBuffer(pixels.data(), 1, static_cast<std::size_t>(image.width));
        out.writePixels(image.height);
    } catch (const std::exception& error) {
        std::error_code ignored;
        std::filesystem::remove(file, ignored);  // never leave a truncated file behind
        throw std::runtime_error("cannot write EXR '" + file.string() + "': " + error.what());
    }
}

}  // namespace lancer
