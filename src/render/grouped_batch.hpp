// Rays traced group by group: a level of the Whitted tree's shadow rays, light by light. Shading emits them
// point by point, each point's rays to every light in turn, so consecutive rays go to different lights and no
// packet of them shares a direction. Grouped (a stable counting sort), the rays of neighbouring points
// towards one light come together and the structure traces them as coherent packets (docs/accel/stream.md,
// docs/whitted.md). The answers come back in the shading order, so the light is added up as before, bit for
// bit.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lancer/ray.hpp"

namespace lancer {

// Answer: InstanceHit (closest hits) or std::uint8_t (occlusion).
template <class Answer>
class GroupedBatch {
  public:
    // answers[i] = rays[i]'s answer, as trace_batch(batch, batch_answers) gives it for a batch of the rays,
    // in one call; group_of_ray[i] < group_count is the group of rays[i]. The buffers are kept between calls.
    template <class Trace>
    void trace(std::span<const Ray> rays, std::span<const std::uint32_t> group_of_ray,
               std::size_t group_count, std::vector<Answer>& answers, Trace&& trace_batch) {
        const std::size_t n = rays.size();
        answers.assign(n, Answer{});
        if (group_count <= 1) return trace_batch(rays, std::span<Answer>(answers));
        std::vector<std::size_t> next(group_count + 1, 0);
        for (const std::uint32_t group : group_of_ray)
            ++next[group + 1];
        for (std::size_t group = 0; group < group_count; ++group)
            next[group + 1] += next[group];
        order_.resize(n);
        grouped_rays_.resize(n);
        for (std::size_t i = 0; i < n; ++i) {
            const std::size_t position = next[group_of_ray[i]]++;
            order_[position] = i;
            grouped_rays_[position] = rays[i];
        }
        grouped_answers_.assign(n, Answer{});
        trace_batch(std::span<const Ray>(grouped_rays_), std::span<Answer>(grouped_answers_));
        for (std::size_t k = 0; k < n; ++k)
            answers[order_[k]] = grouped_answers_[k];
    }

  private:
    std::vector<std::size_t> order_;  // the shading index of each grouped ray
    std::vector<Ray> grouped_rays_;
    std::vector<Answer> grouped_answers_;
};

}  // namespace lancer
