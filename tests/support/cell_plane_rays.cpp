#include "cell_plane_rays.hpp"

#include <random>

namespace lancer::testing {

std::vector<Ray> cell_plane_rays(const Octree& octree, int count, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> level_of(0, 6), axis_of(0, 2);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::vector<Ray> rays;
    const Box3f root = octree.cell_box(octree.cells[0]);
    for (int i = 0; i < count; ++i) {
        Vec3f origin = root.lo + Vec3f(unit(rng), unit(rng), unit(rng)) * root.extent().x;
        if (i % 5 == 0) origin = origin - Vec3f(root.extent().x);
        Vec3f direction(unit(rng) - 0.5f, unit(rng) - 0.5f, unit(rng) - 0.5f);
        const int plane_axis = axis_of(rng), level = level_of(rng);
        std::uniform_int_distribution<std::uint32_t> face(0, 1u << level);
        origin[plane_axis] = octree.cube.plane(plane_axis, level, face(rng));
        direction[plane_axis] = i % 2 ? 0.0f : -0.0f;
        if (i % 3 == 0) {
            const int second = (plane_axis + 1) % 3;
            origin[second] = octree.cube.plane(second, level, face(rng));
            direction[second] = i % 4 ? 0.0f : -0.0f;
        }
        rays.push_back({origin, direction, 0.0f, kInfinity});
    }
    return rays;
}

}  // namespace lancer::testing
