// The shadow rays of one level of the Whitted tree, traced light by light. Shading emits them point by
// point, each point's rays to every light in turn, so consecutive rays go to different lights and no packet
// of them shares a direction. Grouped by light (a stable counting sort), the rays of neighbouring points
// towards one light come together and the structure traces them as coherent packets (docs/accel/stream.md,
// docs/whitted.md). The answers come back in the shading order, so the light is added up as before.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lancer/ray.hpp"

namespace lancer {

class ShadowBatch {
  public:
    // blocked[i] = whether rays[i] is occluded, as occluded(batch, batch_blocked) answers it for a batch of
    // the rays; light_of_ray[i] < light_count is the light rays[i] goes to. The buffers are kept between
    // calls.
    template <class Occluded>
    void trace(std::span<const Ray> rays, std::span<const std::uint32_t> light_of_ray,
               std::size_t light_count, std::vector<std::uint8_t>& blocked, Occluded&& occluded) {
        const std::size_t n = rays.size();
        blocked.assign(n, 0);
        if (light_count <= 1) return occluded(rays, std::span<std::uint8_t>(blocked));
        std::vector<std::size_t> next(light_count + 1, 0);
        for (const std::uint32_t light : light_of_ray)
            ++next[light + 1];
        for (std::size_t light = 0; light < light_count; ++light)
            next[light + 1] += next[light];
        order_.resize(n);
        grouped_rays_.resize(n);
        for (std::size_t i = 0; i < n; ++i) {
            const std::size_t position = next[light_of_ray[i]]++;
            order_[position] = i;
            grouped_rays_[position] = rays[i];
        }
        grouped_blocked_.assign(n, 0);
        occluded(std::span<const Ray>(grouped_rays_), std::span<std::uint8_t>(grouped_blocked_));
        for (std::size_t k = 0; k < n; ++k)
            blocked[order_[k]] = grouped_blocked_[k];
    }

  private:
    std::vector<std::size_t> order_;  // the shading index of each grouped ray
    std::vector<Ray> grouped_rays_;
    std::vector<std::uint8_t> grouped_blocked_;
};

}  // namespace lancer
