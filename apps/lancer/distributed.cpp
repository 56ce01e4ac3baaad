// Job over MPI, where lancer_cli is built with it (apps/lancer/CMakeLists.txt; distributed_stub.cpp
// otherwise): a process mpirun started joins the job, any other is a job of one.
#include <mpi.h>

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <thread>

#include "common.hpp"
#include "distributed.hpp"
#include "frame_message.hpp"
#include "job_failure.hpp"
#include "mpi_transfers.hpp"
#include "tile_counter.hpp"

namespace lancer::cli {
namespace {

// mpirun (Open MPI, or a PMI/PMIx launcher such as MPICH's or Slurm's) marks the processes it starts.
bool started_by_mpirun() {
    for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
        if (std::getenv(name) != nullptr) return true;
    }
    return false;
}

}  // namespace

Job::Job() {
    if (!started_by_mpirun()) return;
    int provided = 0;
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
        fmt::print(stderr, "lancer: MPI_Init failed\n");
        std::exit(1);
    }
    mpi_ = true;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Job::~Job() {
    if (mpi_) MPI_Finalize();
}

void Job::abort(int exit_code) const {
    if (mpi_) MPI_Abort(MPI_COMM_WORLD, exit_code);
    std::exit(exit_code);
}

Job& Job::get() {
    static Job job;
    return job;
}

void Job::on_every_rank(std::string_view what, const std::function<void()>& step) const {
    std::exception_ptr failure;
    try {
        step();
    } catch (...) {
        failure = std::current_exception();
    }
    if (!distributed()) {
        if (failure) std::rethrow_exception(failure);
        return;
    }
    const int mine = failure ? exit_code_of(failure) : 0;
    std::vector<int> codes(static_cast<std::size_t>(size_));
    mpi::check(MPI_Allgather(&mine, 1, MPI_INT, codes.data(), 1, MPI_INT, MPI_COMM_WORLD), "MPI_Allgather");
    std::vector<int> failed;
    for (int r = 0; r < size_; ++r) {
        if (codes[static_cast<std::size_t>(r)] != 0) failed.push_back(r);
    }
    if (failed.empty()) return;
    // The first failing rank's message, for every rank.
    const int first = failed.front();
    std::string message = rank_ == first ? message_of(failure) : std::string();
    int length = static_cast<int>(std::min<std::size_t>(message.size(), 4096));
    mpi::check(MPI_Bcast(&length, 1, MPI_INT, first, MPI_COMM_WORLD), "MPI_Bcast");
    message.resize(static_cast<std::size_t>(length));
    mpi::check(MPI_Bcast(message.data(), length, MPI_CHAR, first, MPI_COMM_WORLD), "MPI_Bcast");
    std::string ranks;
    for (const int r : failed)
        ranks += (ranks.empty() ? "" : ", ") + std::to_string(r);
    throw JobError(fmt::format("{} failed on {} {} of {} (rank {}: {})", what,
                               failed.size() == 1 ? "rank" : "ranks", ranks, size_, first, message),
                   codes[static_cast<std::size_t>(first)]);
}

Image Job::render(const Scene& scene, const SceneGeometry& geometry, const Accel& accel, const Camera& camera,
                  const RenderOptions& options, RenderStats& stats) const {
    if (!distributed()) return lancer::render(scene, geometry, accel, camera, options, &stats);
    const Stopwatch watch;
    const std::size_t tile_count = frame_tile_count(camera, options);
    const int threads =
        options.threads > 0 ? options.threads : static_cast<int>(std::thread::hardware_concurrency());
    // Batches of at least two tiles a thread, and few enough that a rank fetches about 32 of them a frame:
    // each fetch-and-add is a round trip to rank 0.
    const std::size_t batch_size = std::max<std::size_t>(static_cast<std::size_t>(std::max(1, 2 * threads)),
                                                         tile_count / (32 * static_cast<std::size_t>(size_)));
    TileCounter counter(rank_, tile_count, batch_size);
    RenderOptions part_options = options;
    part_options.progress = false;  // rank 0 reports the tiles handed out to every rank instead
    std::exception_ptr failure;
    FramePart part;
    try {
        part = render_part(scene, geometry, accel, camera, part_options, [&] {
            std::vector<std::size_t> batch = counter.next();
            if (options.progress && rank_ == 0)
                fmt::print(stderr, "\rrender: {} of {} tiles handed out to {} ranks", counter.handed_out(),
                           tile_count, size_);
            return batch;
        });
    } catch (...) {
        failure = std::current_exception();
    }
    if (options.progress && rank_ == 0) fmt::print(stderr, "\n");
    // Rank 0 keeps its own part where it is and sends nothing, unless it failed.
    const std::vector<std::byte> bytes = failure
                                             ? serialise(nullptr, message_of(failure), exit_code_of(failure))
                                         : rank_ == 0 ? std::vector<std::byte>()
                                                      : serialise(&part, {}, 0);
    const mpi::Gathered messages = mpi::gather_bytes(bytes, rank_, size_);
    // Rank 0 learns of every failure; it tells the others whether to go on.
    int code = 0;
    std::string message;
    std::vector<FramePart> parts;
    if (rank_ == 0) {
        // Rank 0 must reach the broadcast below whatever it finds here, or the others would wait for it.
        std::vector<std::size_t> failed;
        try {
            if (!failure) parts.push_back(std::move(part));
            for (std::size_t r = 0; r < static_cast<std::size_t>(size_); ++r) {
                if (r == 0 && !failure) continue;
                Reader reader(messages.of(r));
                if (reader.get<std::uint8_t>() == 0) {
                    const auto rank_code = reader.get<std::int32_t>();
                    const std::vector<char> text = reader.get_all<char>();
                    if (failed.empty())
                        code = rank_code,
                        message = fmt::format("rank {}: {}", r, std::string(text.begin(), text.end()));
                    failed.push_back(r);
                    continue;
                }
                parts.push_back(deserialise_part(reader));
            }
        } catch (...) {
            code = exit_code_of(std::current_exception());
            message = "rank 0: " + message_of(std::current_exception());
            failed = {0};
        }
        if (code != 0) {
            std::string ranks;
            for (const std::size_t r : failed)
                ranks += (ranks.empty() ? "" : ", ") + std::to_string(r);
            message = fmt::format("rendering failed on {} {} of {} ({})",
                                  failed.size() == 1 ? "rank" : "ranks", ranks, size_, message);
        }
    }
    mpi::check(MPI_Bcast(&code, 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Bcast");
    if (code != 0) throw JobError(rank_ == 0 ? message : "rendering failed on another rank", code);
    if (rank_ != 0) return {};
    Image image = assemble_frame(camera, options, parts, &stats);
    stats.trace_ms = watch.elapsed_ms();
    return image;
}

std::vector<Hit> Job::intersect(const Accel& accel, const std::vector<Ray>& rays, int threads) const {
    if (!distributed()) {
        std::vector<Hit> hits(rays.size());
        intersect_parallel(accel, rays, hits, threads);
        return hits;
    }
    std::uint64_t count = rank_ == 0 ? rays.size() : 0;
    mpi::check(MPI_Bcast(&count, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD), "MPI_Bcast");
    const auto [counts, offsets] = mpi::slices(count, size_);
    const mpi::RecordType<Ray> ray_type;
    const mpi::RecordType<Hit> hit_type;
    const auto mine = static_cast<std::size_t>(counts[static_cast<std::size_t>(rank_)]);
    std::vector<Ray> slice(mine);
    mpi::check(MPI_Scatterv(rays.data(), counts.data(), offsets.data(), ray_type.get(), slice.data(),
                            static_cast<int>(mine), ray_type.get(), 0, MPI_COMM_WORLD),
               "MPI_Scatterv");
    std::vector<Hit> slice_hits(mine);
    on_every_rank("tracing the rays", [&] { intersect_parallel(accel, slice, slice_hits, threads); });
    std::vector<Hit> hits(rank_ == 0 ? count : 0);
    mpi::check(MPI_Gatherv(slice_hits.data(), static_cast<int>(mine), hit_type.get(), hits.data(),
                           counts.data(), offsets.data(), hit_type.get(), 0, MPI_COMM_WORLD),
               "MPI_Gatherv");
    return hits;
}

void Job::barrier() const {
    if (!distributed()) return;
    // Polled with short sleeps, not MPI_Barrier: Open MPI spins a core in a blocking call, which would take
    // it from a rank still working on the same machine (bench --mpi times rank 0 alone while the others
    // wait here).
    MPI_Request request = MPI_REQUEST_NULL;
    mpi::check(MPI_Ibarrier(MPI_COMM_WORLD, &request), "MPI_Ibarrier");
    for (int done = 0;;) {
        mpi::check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), "MPI_Test");
        if (done != 0) return;
        std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
}

double Job::max_over_ranks(double value) const {
    if (distributed()) {
        double largest = value;
        mpi::check(MPI_Allreduce(&value, &largest, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD), "MPI_Allreduce");
        return largest;
    }
    return value;
}

}  // namespace lancer::cli
