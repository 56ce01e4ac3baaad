#include "mpi_transfers.hpp"

#include <fmt/core.h>

#include <climits>
#include <stdexcept>
#include <string>

#include "distributed.hpp"

namespace lancer::cli::mpi {

void check(int status, const char* call) {
    if (status != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + call + " failed");
}

Gathered gather_bytes(const std::vector<std::byte>& mine, int rank, int size) {
    if (mine.size() > static_cast<std::size_t>(INT_MAX))
        throw std::runtime_error("MPI: a rank's part of the frame is over 2 GiB; use more ranks");
    const int my_count = static_cast<int>(mine.size());
    Gathered gathered;
    gathered.counts.resize(static_cast<std::size_t>(size));
    gathered.offsets.resize(static_cast<std::size_t>(size));
    check(MPI_Gather(&my_count, 1, MPI_INT, gathered.counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD),
          "MPI_Gather");
    if (rank == 0) {
        std::size_t total = 0;
        for (std::size_t r = 0; r < gathered.counts.size(); ++r) {
            if (total > static_cast<std::size_t>(INT_MAX))
                throw std::runtime_error("MPI: the frame's parts are over 2 GiB in all");
            gathered.offsets[r] = static_cast<int>(total);
            total += static_cast<std::size_t>(gathered.counts[r]);
        }
        gathered.bytes.resize(total);
    }
    check(MPI_Gatherv(mine.data(), my_count, MPI_BYTE, gathered.bytes.data(), gathered.counts.data(),
                      gathered.offsets.data(), MPI_BYTE, 0, MPI_COMM_WORLD),
          "MPI_Gatherv");
    return gathered;
}

std::pair<std::vector<int>, std::vector<int>> slices(std::uint64_t n, int size) {
    std::vector<int> counts(static_cast<std::size_t>(size)), offsets(static_cast<std::size_t>(size));
    std::uint64_t first = 0;
    for (int r = 0; r < size; ++r) {
        const std::uint64_t count =
            n / static_cast<std::uint64_t>(size) +
            (static_cast<std::uint64_t>(r) < n % static_cast<std::uint64_t>(size) ? 1 : 0);
        if (first + count > static_cast<std::uint64_t>(INT_MAX))
            throw JobError(
                fmt::format("{} rays are more than {} ranks can take in one batch (2^31 a rank in all)", n,
                            size),
                2);
        counts[static_cast<std::size_t>(r)] = static_cast<int>(count);
        offsets[static_cast<std::size_t>(r)] = static_cast<int>(first);
        first += count;
    }
    return {counts, offsets};
}

}  // namespace lancer::cli::mpi
