// Writes the plo harness's seed corpus (scripts/fuzz.sh): small Plücker octree files in every layout
// variant and both triangle tests, so that mutations start from files that read.
#include <cstdio>
#include <filesystem>
#include <string>

#include "accel/plucker/plucker.hpp"
#include "accel/plucker/serialise.hpp"
#include "lancer/generate.hpp"

int main(int argc, char** argv) {
    using namespace lancer;
    if (argc != 2) {
        std::fprintf(stderr, "usage: make_plo_seeds FOLDER\n");
        return 2;
    }
    const std::filesystem::path folder = argv[1];
    std::filesystem::create_directories(folder);
    const std::vector<Triangle> triangles = make_icosphere(1).triangles();
    const std::vector<Sphere> spheres = {{Vec3f(0.5f, 0.0f, 0.0f), 0.25f, 0}};
    const Geometry geometries[] = {{triangles, {}}, {triangles, spheres}, {{triangles.data(), 2}, {}}};
    int written = 0;
    for (const Geometry& geometry : geometries) {
        for (int variant = 0; variant < 4; ++variant) {
            BuildOptions options =
                build_options(variant % 2 == 0 ? TriangleTest::MollerTrumbore : TriangleTest::Watertight);
            options.group<PluckerOptions>().max_depth = 3;
            options.group<PluckerOptions>().leaf_size = 4;
            options.group<PluckerOptions>().balanced = variant != 1;
            options.group<PluckerOptions>().stored_boxes = variant != 2;
            options.group<PluckerOptions>().morton = variant == 3;
            PluckerAccel accel;
            accel.build(geometry, options);
            plucker::write_plucker_file(folder / ("seed" + std::to_string(written++) + ".plo"), geometry,
                                        accel.layout(), options.triangle_test);
        }
    }
    std::printf("%d .plo seeds in %s\n", written, folder.c_str());
    return 0;
}
