#include "tile_counter.hpp"

#include <algorithm>

#include "mpi_transfers.hpp"

namespace lancer::cli {

TileCounter::TileCounter(int rank, std::size_t tile_count, std::size_t batch)
    : tile_count_(tile_count), batch_(batch) {
    mpi::check(MPI_Win_allocate(rank == 0 ? static_cast<MPI_Aint>(sizeof(std::uint64_t)) : 0,
                                sizeof(std::uint64_t), MPI_INFO_NULL, MPI_COMM_WORLD, &counter_, &window_),
               "MPI_Win_allocate");
    if (rank == 0) {
        mpi::check(MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, window_), "MPI_Win_lock");
        *counter_ = 0;
        mpi::check(MPI_Win_unlock(0, window_), "MPI_Win_unlock");
    }
    mpi::check(MPI_Barrier(MPI_COMM_WORLD), "MPI_Barrier");
}

std::vector<std::size_t> TileCounter::next() {
    const auto step = static_cast<std::uint64_t>(batch_);
    std::uint64_t first = 0;
    mpi::check(MPI_Win_lock(MPI_LOCK_SHARED, 0, 0, window_), "MPI_Win_lock");
    mpi::check(MPI_Fetch_and_op(&step, &first, MPI_UINT64_T, 0, 0, MPI_SUM, window_), "MPI_Fetch_and_op");
    mpi::check(MPI_Win_unlock(0, window_), "MPI_Win_unlock");
    std::vector<std::size_t> tiles;
    for (std::uint64_t tile = first; tile < first + step && tile < tile_count_; ++tile)
        tiles.push_back(static_cast<std::size_t>(tile));
    handed_out_ = std::min<std::uint64_t>(first + step, tile_count_);
    return tiles;
}

}  // namespace lancer::cli
