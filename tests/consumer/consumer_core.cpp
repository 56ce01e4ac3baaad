// lancer::core alone: two triangles in memory, every registered structure, rays that must hit or miss them.
#include <lancer/accel.hpp>

#include <cstdio>
#include <vector>

int main() {
    using namespace lancer;
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}},
                                             {{1, 0, 0}, {1, 1, 0}, {0, 1, 0}}};
    const Geometry geometry{triangles, {}};
    const std::vector<Ray> rays = {{{0.25f, 0.25f, 1}, {0, 0, -1}, 0.0f, kInfinity},
                                   {{0.75f, 0.75f, 1}, {0, 0, -1}, 0.0f, kInfinity},
                                   {{2.0f, 2.0f, 1}, {0, 0, -1}, 0.0f, kInfinity}};
    const int expected[] = {0, 1, -1};
    int failures = 0;
    for (const std::string_view name : accel_names()) {
        const std::unique_ptr<Accel> accel = make_accel(name);
        accel->build(geometry, build_options(TriangleTest::Watertight));
        std::vector<Hit> hits(rays.size());
        accel->intersect(rays, hits);
        for (std::size_t i = 0; i < rays.size(); ++i) {
            if (hits[i].prim != expected[i]) {
                std::printf("%.*s: ray %zu hit %d, expected %d\n", static_cast<int>(name.size()), name.data(),
                            i, hits[i].prim, expected[i]);
                ++failures;
            }
        }
    }
    std::printf("lancer::core: %zu structures, %d wrong answers\n", accel_names().size(), failures);
    return failures == 0 ? 0 : 1;
}
