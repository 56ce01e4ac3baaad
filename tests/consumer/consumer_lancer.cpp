// lancer::lancer: a generated sphere in a World, the canonical view's rays, every hit checked against brute
// force, and one frame rendered.
#include <lancer/agreement.hpp>
#include <lancer/camera.hpp>
#include <lancer/generate.hpp>
#include <lancer/render.hpp>
#include <lancer/world.hpp>

#include <cstdio>
#include <vector>

int main() {
    using namespace lancer;
    Scene scene;
    scene.meshes.push_back(make_icosphere(3));
    scene.materials.emplace_back();
    const World world(std::move(scene), "bvh8", build_options(TriangleTest::Watertight));
    const World oracle(world.scene(), "brute", build_options(TriangleTest::Watertight));
    const Camera camera = canonical_view(world.scene().bounds(), 64, 64);
    const std::vector<Ray> rays = PinholeCamera(camera).pixel_centre_rays(0, 0, 64, 64);
    std::vector<Hit> hits(rays.size()), expected(rays.size());
    world.accel().intersect(rays, hits);
    oracle.accel().intersect(rays, expected);
    const Agreement agreement = compare_hits(rays, expected, hits);
    const Image image = render(world, camera, RenderOptions{});
    std::printf("lancer::lancer: %s; image %dx%d\n", agreement.summary().c_str(), image.width, image.height);
    return agreement.mismatches == 0 && agreement.hits > 0 && image.width == 64 ? 0 : 1;
}
