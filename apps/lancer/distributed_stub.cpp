// Job without MPI (LANCER_MPI off, or no MPI found: apps/lancer/CMakeLists.txt): every job is this process
// alone, and every call the single-process one.
#include <cstdlib>

#include "distributed.hpp"

namespace lancer::cli {

Job::Job() = default;

Job::~Job() = default;

void Job::abort(int exit_code) const {
    std::exit(exit_code);
}

Job& Job::get() {
    static Job job;
    return job;
}

void Job::on_every_rank(std::string_view /*what*/, const std::function<void()>& step) const {
    step();
}

Image Job::render(const Scene& scene, const SceneGeometry& geometry, const Accel& accel, const Camera& camera,
                  const RenderOptions& options, RenderStats& stats) const {
    return lancer::render(scene, geometry, accel, camera, options, &stats);
}

std::vector<Hit> Job::intersect(const Accel& accel, const std::vector<Ray>& rays, int threads) const {
    std::vector<Hit> hits(rays.size());
    intersect_parallel(accel, rays, hits, threads);
    return hits;
}

void Job::barrier() const {}

double Job::max_over_ranks(double value) const {
    return value;
}

}  // namespace lancer::cli
