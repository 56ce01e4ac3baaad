// The processes of an `mpirun` job (docs/distributed.md). Work is spread the way OSPRay's MPI offload device
// spreads it: image-parallel, the scene loaded and its structure built on every rank. Without MPI (the
// CMake option LANCER_MPI off) or outside mpirun, the job is this process alone and every call below is the
// single-process one.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/render.hpp"

namespace lancer::cli {

// A failure every rank of the job knows of, with one message: each rank ends with the same exit code, and
// rank 0 alone prints it.
class JobError : public std::runtime_error {
  public:
    JobError(const std::string& message, int exit_code)
        : std::runtime_error(message), exit_code_(exit_code) {}
    [[nodiscard]] int exit_code() const { return exit_code_; }

  private:
    int exit_code_;
};

class Job {
  public:
    // The job of this process. The first call initialises MPI when mpirun started the process (its
    // environment says so), so that a plain `lancer` run never touches MPI.
    static Job& get();
    ~Job();
    Job(const Job&) = delete;
    Job& operator=(const Job&) = delete;

    [[nodiscard]] int rank() const { return rank_; }
    [[nodiscard]] int size() const { return size_; }
    [[nodiscard]] bool distributed() const { return size_ > 1; }
    [[nodiscard]] bool is_root() const { return rank_ == 0; }

    // Runs `step` on every rank, then compares notes: when it threw on any rank, every rank throws a
    // JobError saying `what` failed on which ranks and why (the first failing rank's message), with that
    // rank's exit code (2 for bad input or memory, 1 otherwise). No rank is left waiting for another.
    void on_every_rank(std::string_view what, const std::function<void()>& step) const;

    // Ends this process with `exit_code`, and under mpirun the whole job with it (MPI_Abort): for a
    // failure the other ranks cannot learn of, while they may be waiting for this one.
    [[noreturn]] void abort(int exit_code) const;

    // The frame rendered over the ranks: tiles handed out in batches from a counter that rank 0 keeps,
    // every part gathered and assembled on rank 0. Returns the image on rank 0 (an empty one elsewhere),
    // and there the rays of all ranks in `stats`. A rank that fails while rendering makes every rank throw
    // a JobError.
    [[nodiscard]] Image render(const Scene& scene, const SceneGeometry& geometry, const Accel& accel,
                               const Camera& camera, const RenderOptions& options, RenderStats& stats) const;

    // Closest hits of `rays` (read on rank 0; ignored elsewhere), split among the ranks in contiguous
    // slices: scattered, traced over `threads` threads a rank, gathered back in order on rank 0.
    [[nodiscard]] std::vector<Hit> intersect(const Accel& accel, const std::vector<Ray>& rays,
                                             int threads) const;

    // Waits for every rank, without spinning a core meanwhile.
    void barrier() const;

    // The largest of every rank's `value` (rank 0's view of the slowest rank's time, for instance).
    [[nodiscard]] double max_over_ranks(double value) const;

  private:
    Job();
    int rank_ = 0;
    int size_ = 1;
    [[maybe_unused]] bool mpi_ = false;  // read only where MPI is built in (LANCER_HAS_MPI)
};

}  // namespace lancer::cli
