#include "render/heatmap.hpp"

#include <algorithm>
#include <array>
#include <string>

namespace lancer {
namespace {

// Five stops sampled from matplotlib's "inferno" (perceptually uniform, readable in grey).
constexpr std::array<Vec3f, 5> kRamp = {Vec3f(0.0f, 0.0f, 0.02f), Vec3f(0.34f, 0.06f, 0.43f),
                                        Vec3f(0.73f, 0.21f, 0.33f), Vec3f(0.98f, 0.55f, 0.04f),
                                        Vec3f(0.99f, 1.0f, 0.64f)};

// 3x5 pixel digits, one row per 3-bit pattern, most significant bit on the left.
constexpr std::array<std::array<std::uint8_t, 5>, 10> kDigits = {{{7, 5, 5, 5, 7},
                                                                  {2, 6, 2, 2, 7},
                                                                  {7, 1, 7, 4, 7},
                                                                  {7, 1, 7, 1, 7},
                                                                  {5, 5, 7, 1, 1},
                                                                  {7, 4, 7, 1, 7},
                                                                  {7, 4, 7, 5, 7},
                                                                  {7, 1, 1, 1, 1},
                                                                  {7, 5, 7, 5, 7},
                                                                  {7, 5, 7, 1, 7}}};

void fill(Image& image, int x0, int y0, int width, int height, Vec3f color) {
    for (int y = std::max(y0, 0); y < std::min(y0 + height, image.height); ++y) {
        for (int x = std::max(x0, 0); x < std::min(x0 + width, image.width); ++x)
            image.at(x, y) = color;
    }
}

// Digits `scale` pixels per font pixel, white; returns the width drawn.
int draw_number(Image& image, int x0, int y0, std::uint32_t value, int scale) {
    const std::string text = std::to_string(value);
    int x = x0;
    for (char c : text) {
        const auto& rows = kDigits[static_cast<std::size_t>(c - '0')];
        for (int row = 0; row < 5; ++row) {
            for (int column = 0; column < 3; ++column) {
                if (rows[static_cast<std::size_t>(row)] & (4 >> column)) {
                    fill(image, x + column * scale, y0 + row * scale, scale, scale, Vec3f(1.0f));
                }
            }
        }
        x += 4 * scale;
    }
    return x - x0;
}

}  // namespace

Vec3f heat_color(float fraction) {
    const float position = std::clamp(fraction, 0.0f, 1.0f) * static_cast<float>(kRamp.size() - 1);
    const auto stop = std::min(static_cast<std::size_t>(position), kRamp.size() - 2);
    const float blend = position - static_cast<float>(stop);
    return (1.0f - blend) * kRamp[stop] + blend * kRamp[stop + 1];
}

void heat_to_image(std::span<const std::uint32_t> counts, Image& image) {
    const std::uint32_t maximum = counts.empty() ? 0 : *std::max_element(counts.begin(), counts.end());
    const float scale = maximum > 0 ? 1.0f / static_cast<float>(maximum) : 0.0f;
    for (std::size_t i = 0; i < counts.size(); ++i) {
        image.pixels[i] = heat_color(static_cast<float>(counts[i]) * scale);
    }
    // Legend: about a quarter of the width, on a dark backdrop; small images get no legend.
    const int font = std::max(1, image.height / 256);
    const int bar_width = image.width / 4, bar_height = 6 * font, margin = 3 * font;
    const int legend_height = bar_height + 5 * font + 3 * margin;
    if (bar_width < 32 || legend_height * 4 > image.height) return;
    const int x0 = margin, y0 = image.height - legend_height - margin;
    fill(image, x0 - margin, y0 - margin, bar_width + 2 * margin, legend_height + margin, Vec3f(0.05f));
    for (int x = 0; x < bar_width; ++x) {
        fill(image, x0 + x, y0, 1, bar_height,
             heat_color(static_cast<float>(x) / static_cast<float>(bar_width - 1)));
    }
    const int label_y = y0 + bar_height + margin;
    draw_number(image, x0, label_y, 0, font);
    const int max_width = static_cast<int>(std::to_string(maximum).size()) * 4 * font - font;
    draw_number(image, x0 + bar_width - max_width, label_y, maximum, font);
}

}  // namespace lancer
