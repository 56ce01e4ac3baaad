// lancer bench --instances N: a two-level scene of N copies of a mesh under random rotations, scales and
// positions (lancer/instances.hpp), traced on the views of VIEWS.md beside Embree's two-level scene on the
// same instances and rays, and the top level's update for N moving instances beside Embree's.
#pragma once

#include <string>
#include <vector>

#include "bench_report.hpp"
#include "lancer/scene.hpp"

namespace lancer::cli {

struct InstancesBenchOptions {
    int instances = 0;
    std::vector<int> thread_counts;
    std::vector<BenchView> views;
    // lancer's structures for the object (bvh8, bvh8_packet, any other), and Embree's calls on its two-level
    // scene (embree: rtcIntersect1, embree8, embree16, embree_stream: rtcIntersect1M).
    std::vector<std::string> accels;
    int size = 1024;
    int frames = 5;
    bool watertight = true;
    std::vector<std::string> settings;
};

// Throws InputError for an unknown structure or a mesh without triangles, CheckFailure when lancer's
// structures disagree with each other.
void run_instances_bench(const std::string& mesh_name, const Scene& mesh,
                         const InstancesBenchOptions& options);

}  // namespace lancer::cli
