// lancer bench --animate N: each mesh deformed over N frames by the documented sine wave
// (lancer/animate.hpp); per frame and structure, the update (a refit for the BVHs, Embree's refit quality for
// the Embree rows) and a trace of the canonical view, beside full rebuilds on the same frames.
// docs/accel/refit.md has the design and the figures.
#pragma once

#include <string>
#include <vector>

#include "lancer/scene.hpp"

namespace lancer::cli {

struct AnimatedBenchMesh {
    std::string name;
    const Scene* scene = nullptr;
};

struct AnimatedBenchOptions {
    int frames = 8;
    std::vector<int> thread_counts;
    std::vector<std::string> accels;
    int size = 1024;
    bool watertight = true;
    std::vector<std::string> settings;
    std::string json_file;
};

// Prints the per-frame table and each row's medians. Throws CheckFailure when one of lancer's structures
// disagrees with the first row on a frame's closest hits.
void run_animated_bench(const std::vector<AnimatedBenchMesh>& meshes, const AnimatedBenchOptions& options);

}  // namespace lancer::cli
