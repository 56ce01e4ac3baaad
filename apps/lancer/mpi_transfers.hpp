// The MPI calls a distributed Job makes, wrapped (docs/distributed.md): a failed call as an exception, a
// rank's bytes gathered on rank 0, rays and hits sent as records of their size, a batch cut into the ranks'
// slices.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace lancer::cli::mpi {

// Throws std::runtime_error naming `call` unless `status` is MPI_SUCCESS.
void check(int status, const char* call);

// Every rank's bytes, on rank 0 (elsewhere: nothing): one buffer, rank r's bytes at [offsets[r],
// offsets[r] + counts[r]).
struct Gathered {
    std::vector<std::byte> bytes;
    std::vector<int> counts, offsets;

    [[nodiscard]] std::span<const std::byte> of(std::size_t rank) const {
        return std::span(bytes).subspan(static_cast<std::size_t>(offsets[rank]),
                                        static_cast<std::size_t>(counts[rank]));
    }
};

[[nodiscard]] Gathered gather_bytes(const std::vector<std::byte>& mine, int rank, int size);

// A Ray or a Hit as an MPI type of its size, so that counts are of records, not bytes.
template <class T>
class RecordType {
  public:
    RecordType() {
        check(MPI_Type_contiguous(static_cast<int>(sizeof(T)), MPI_BYTE, &type_), "MPI_Type_contiguous");
        check(MPI_Type_commit(&type_), "MPI_Type_commit");
    }
    ~RecordType() { MPI_Type_free(&type_); }
    RecordType(const RecordType&) = delete;
    RecordType& operator=(const RecordType&) = delete;
    [[nodiscard]] MPI_Datatype get() const { return type_; }

  private:
    MPI_Datatype type_ = MPI_DATATYPE_NULL;
};

// Rank r's slice of n records, as MPI_Scatterv's and MPI_Gatherv's counts and offsets: contiguous, the
// first n % size ranks one longer. Throws a JobError (2) past 2^31 records in all.
[[nodiscard]] std::pair<std::vector<int>, std::vector<int>> slices(std::uint64_t n, int size);

}  // namespace lancer::cli::mpi
