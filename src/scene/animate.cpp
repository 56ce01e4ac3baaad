#include "lancer/animate.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "core/parallel.hpp"

namespace lancer {

void SineWave::apply(std::span<const Vec3f> rest, int frame, std::span<Vec3f> out) const {
    if (out.size() != rest.size())
        throw std::invalid_argument("SineWave::apply: one output per rest position");
    if (frame_count < 1) throw std::invalid_argument("SineWave::apply: frame_count must be at least 1");
    const Vec3f extent = bounds.extent();
    const double largest = std::max({extent.x, extent.y, extent.z, 0.0f});
    const double lift = static_cast<double>(amplitude) * largest;
    // A box flat along x has no wavelength: the whole mesh then rises and falls together.
    const double wavenumber = extent.x > 0.0f ? 2.0 * std::numbers::pi / extent.x : 0.0;
    const double phase = 2.0 * std::numbers::pi * (frame % frame_count) / frame_count;
    constexpr std::size_t kGrain = 1 << 14;
    parallel::for_each_chunk(0, rest.size(), kGrain, [&](std::size_t from, std::size_t to) {
        for (std::size_t i = from; i < to; ++i) {
            const Vec3f p = rest[i];
            const double offset = lift * std::sin(wavenumber * (p.x - bounds.lo.x) - phase);
            out[i] = {p.x, static_cast<float>(p.y + offset), p.z};
        }
    });
}

std::vector<std::vector<Vec3f>> deformed_meshes(const Scene& scene, const SineWave& wave, int frame) {
    std::vector<std::vector<Vec3f>> moved;
    moved.reserve(scene.meshes.size());
    for (const TriangleMesh& mesh : scene.meshes) {
        std::vector<Vec3f>& positions = moved.emplace_back(mesh.positions.size());
        wave.apply(mesh.positions, frame, positions);
    }
    return moved;
}

}  // namespace lancer
