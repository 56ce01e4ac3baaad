// The tiles of a distributed frame, handed out to the ranks in batches (docs/distributed.md).
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace lancer::cli {

// The tiles of a frame handed out in batches: a counter in an MPI window on rank 0, which every rank
// (rank 0 too) advances by one atomic fetch-and-add per batch (passive-target one-sided communication, so
// that rank 0 renders tiles as well and serves no requests). Which rank renders which tile varies from run
// to run; the image does not (assemble_frame).
class TileCounter {
  public:
    // Collective: every rank constructs its counter together; the counter starts at tile 0.
    TileCounter(int rank, std::size_t tile_count, std::size_t batch);
    ~TileCounter() { MPI_Win_free(&window_); }
    TileCounter(const TileCounter&) = delete;
    TileCounter& operator=(const TileCounter&) = delete;

    // The next batch of tiles, empty once every tile is handed out.
    std::vector<std::size_t> next();
    // Tiles handed out to every rank when this rank last asked.
    [[nodiscard]] std::uint64_t handed_out() const { return handed_out_; }

  private:
    std::size_t tile_count_;
    std::size_t batch_;
    std::uint64_t* counter_ = nullptr;
    MPI_Win window_ = MPI_WIN_NULL;
    std::uint64_t handed_out_ = 0;
};

}  // namespace lancer::cli
