#include "distributed.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <span>
#include <thread>
#include <type_traits>

#include "common.hpp"
#include "lancer/load_scene.hpp"

#if LANCER_HAS_MPI
#include <mpi.h>
#endif

namespace lancer::cli {
namespace {

#if LANCER_HAS_MPI
// The exit code a failure gives the whole job: 2 for bad input (a file, an option) and memory, as main()
// gives them, 1 for the rest.
int exit_code_of(const std::exception_ptr& failure) {
    try {
        std::rethrow_exception(failure);
    } catch (const LoadError&) {
        return 2;
    } catch (const InputError&) {
        return 2;
    } catch (const std::bad_alloc&) {
        return 2;
    } catch (const JobError& error) {
        return error.exit_code();
    } catch (...) {
        return 1;
    }
}

std::string message_of(const std::exception_ptr& failure) {
    try {
        std::rethrow_exception(failure);
    } catch (const std::bad_alloc&) {
        return out_of_memory("the job's data", "running").what();
    } catch (const std::exception& error) {
        return error.what();
    } catch (...) {
        return "an unknown error";
    }
}

// mpirun (Open MPI, or a PMI/PMIx launcher such as MPICH's or Slurm's) marks the processes it starts.
bool started_by_mpirun() {
    for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
        if (std::getenv(name) != nullptr) return true;
    }
    return false;
}

void check(int status, const char* call) {
    if (status != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + call + " failed");
}

// Bytes appended to, and read back from, a buffer sent in one message.
class Writer {
  public:
    template <class T>
    void put(const T& value) {
        static_assert(std::is_trivially_copyable_v<T>);
        const auto* bytes = reinterpret_cast<const std::byte*>(&value);
        buffer_.insert(buffer_.end(), bytes, bytes + sizeof(T));
    }
    template <class T>
    void put_all(std::span<const T> values) {
        static_assert(std::is_trivially_copyable_v<T>);
        put(static_cast<std::uint64_t>(values.size()));
        const auto* bytes = reinterpret_cast<const std::byte*>(values.data());
        buffer_.insert(buffer_.end(), bytes, bytes + values.size_bytes());
    }
    [[nodiscard]] std::vector<std::byte>& bytes() { return buffer_; }

  private:
    std::vector<std::byte> buffer_;
};

class Reader {
  public:
    explicit Reader(std::span<const std::byte> bytes) : bytes_(bytes) {}
    template <class T>
    T get() {
        T value;
        take(&value, sizeof(T));
        return value;
    }
    template <class T>
    std::vector<T> get_all() {
        const auto count = get<std::uint64_t>();
        if (count > (bytes_.size() - offset_) / sizeof(T))
            throw std::runtime_error("MPI: a message is cut short");
        std::vector<T> values(static_cast<std::size_t>(count));
        take(values.data(), values.size() * sizeof(T));
        return values;
    }

  private:
    void take(void* out, std::size_t size) {
        if (size > bytes_.size() - offset_) throw std::runtime_error("MPI: a message is cut short");
        std::memcpy(out, bytes_.data() + offset_, size);
        offset_ += size;
    }
    std::span<const std::byte> bytes_;
    std::size_t offset_ = 0;
};

// A rank's part of the frame, or why it has none: the message every rank sends rank 0 at the end.
std::vector<std::byte> serialise(const FramePart* part, const std::string& failure, int exit_code) {
    Writer writer;
    writer.put(static_cast<std::uint8_t>(part != nullptr ? 1 : 0));
    if (part == nullptr) {
        writer.put(static_cast<std::int32_t>(exit_code));
        writer.put_all(std::span<const char>(failure));
        return std::move(writer.bytes());
    }
    writer.put_all(std::span<const std::size_t>(part->tiles));
    writer.put_all(std::span<const Vec3f>(part->pixels));
    writer.put_all(std::span<const float>(part->depth));
    writer.put_all(std::span<const TraversalCounters>(part->heat));
    writer.put(part->stats.primary_rays), writer.put(part->stats.shadow_rays);
    writer.put(part->stats.reflection_rays), writer.put(part->stats.refraction_rays);
    return std::move(writer.bytes());
}

// serialise's inverse for a part (the leading 1 already read).
FramePart deserialise_part(Reader& reader) {
    FramePart part;
    part.tiles = reader.get_all<std::size_t>();
    part.pixels = reader.get_all<Vec3f>();
    part.depth = reader.get_all<float>();
    part.heat = reader.get_all<TraversalCounters>();
    part.stats.primary_rays = reader.get<std::uint64_t>();
    part.stats.shadow_rays = reader.get<std::uint64_t>();
    part.stats.reflection_rays = reader.get<std::uint64_t>();
    part.stats.refraction_rays = reader.get<std::uint64_t>();
    return part;
}

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

// The tiles of a frame handed out in batches: a counter in an MPI window on rank 0, which every rank
// (rank 0 too) advances by one atomic fetch-and-add per batch (passive-target one-sided communication, so
// that rank 0 renders tiles as well and serves no requests). Which rank renders which tile varies from run
// to run; the image does not (assemble_frame).
class TileCounter {
  public:
    TileCounter(int rank, std::size_t tile_count, std::size_t batch)
        : tile_count_(tile_count), batch_(batch) {
        check(MPI_Win_allocate(rank == 0 ? static_cast<MPI_Aint>(sizeof(std::uint64_t)) : 0,
                               sizeof(std::uint64_t), MPI_INFO_NULL, MPI_COMM_WORLD, &counter_, &window_),
              "MPI_Win_allocate");
        if (rank == 0) {
            check(MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, window_), "MPI_Win_lock");
            *counter_ = 0;
            check(MPI_Win_unlock(0, window_), "MPI_Win_unlock");
        }
        check(MPI_Barrier(MPI_COMM_WORLD), "MPI_Barrier");
    }
    ~TileCounter() { MPI_Win_free(&window_); }
    TileCounter(const TileCounter&) = delete;
    TileCounter& operator=(const TileCounter&) = delete;

    // The next batch of tiles, empty once every tile is handed out.
    std::vector<std::size_t> next() {
        const auto step = static_cast<std::uint64_t>(batch_);
        std::uint64_t first = 0;
        check(MPI_Win_lock(MPI_LOCK_SHARED, 0, 0, window_), "MPI_Win_lock");
        check(MPI_Fetch_and_op(&step, &first, MPI_UINT64_T, 0, 0, MPI_SUM, window_), "MPI_Fetch_and_op");
        check(MPI_Win_unlock(0, window_), "MPI_Win_unlock");
        std::vector<std::size_t> tiles;
        for (std::uint64_t tile = first; tile < first + step && tile < tile_count_; ++tile)
            tiles.push_back(static_cast<std::size_t>(tile));
        handed_out_ = std::min<std::uint64_t>(first + step, tile_count_);
        return tiles;
    }
    // Tiles handed out to every rank when this rank last asked.
    [[nodiscard]] std::uint64_t handed_out() const { return handed_out_; }

  private:
    std::size_t tile_count_;
    std::size_t batch_;
    std::uint64_t* counter_ = nullptr;
    MPI_Win window_ = MPI_WIN_NULL;
    std::uint64_t handed_out_ = 0;
};

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

// Rank r's slice of n records: contiguous, the first n % size ranks one longer.
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
#endif

}  // namespace

Job::Job() {
#if LANCER_HAS_MPI
    if (!started_by_mpirun()) return;
    int provided = 0;
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
        fmt::print(stderr, "lancer: MPI_Init failed\n");
        std::exit(1);
    }
    mpi_ = true;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
#endif
}

Job::~Job() {
#if LANCER_HAS_MPI
    if (mpi_) MPI_Finalize();
#endif
}

void Job::abort(int exit_code) const {
#if LANCER_HAS_MPI
    if (mpi_) MPI_Abort(MPI_COMM_WORLD, exit_code);
#endif
    std::exit(exit_code);
}

Job& Job::get() {
    static Job job;
    return job;
}

void Job::on_every_rank([[maybe_unused]] std::string_view what, const std::function<void()>& step) const {
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
#if LANCER_HAS_MPI
    const int mine = failure ? exit_code_of(failure) : 0;
    std::vector<int> codes(static_cast<std::size_t>(size_));
    check(MPI_Allgather(&mine, 1, MPI_INT, codes.data(), 1, MPI_INT, MPI_COMM_WORLD), "MPI_Allgather");
    std::vector<int> failed;
    for (int r = 0; r < size_; ++r) {
        if (codes[static_cast<std::size_t>(r)] != 0) failed.push_back(r);
    }
    if (failed.empty()) return;
    // The first failing rank's message, for every rank.
    const int first = failed.front();
    std::string message = rank_ == first ? message_of(failure) : std::string();
    int length = static_cast<int>(std::min<std::size_t>(message.size(), 4096));
    check(MPI_Bcast(&length, 1, MPI_INT, first, MPI_COMM_WORLD), "MPI_Bcast");
    message.resize(static_cast<std::size_t>(length));
    check(MPI_Bcast(message.data(), length, MPI_CHAR, first, MPI_COMM_WORLD), "MPI_Bcast");
    std::string ranks;
    for (const int r : failed)
        ranks += (ranks.empty() ? "" : ", ") + std::to_string(r);
    throw JobError(fmt::format("{} failed on {} {} of {} (rank {}: {})", what,
                               failed.size() == 1 ? "rank" : "ranks", ranks, size_, first, message),
                   codes[static_cast<std::size_t>(first)]);
#endif
}

Image Job::render(const Scene& scene, const SceneGeometry& geometry, const Accel& accel, const Camera& camera,
                  const RenderOptions& options, RenderStats& stats) const {
    if (!distributed()) return lancer::render(scene, geometry, accel, camera, options, &stats);
#if LANCER_HAS_MPI
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
    const Gathered messages = gather_bytes(bytes, rank_, size_);
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
    check(MPI_Bcast(&code, 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Bcast");
    if (code != 0) throw JobError(rank_ == 0 ? message : "rendering failed on another rank", code);
    if (rank_ != 0) return {};
    Image image = assemble_frame(camera, options, parts, &stats);
    stats.trace_ms = watch.elapsed_ms();
    return image;
#else
    return {};
#endif
}

std::vector<Hit> Job::intersect(const Accel& accel, const std::vector<Ray>& rays, int threads) const {
    if (!distributed()) {
        std::vector<Hit> hits(rays.size());
        intersect_parallel(accel, rays, hits, threads);
        return hits;
    }
#if LANCER_HAS_MPI
    std::uint64_t count = rank_ == 0 ? rays.size() : 0;
    check(MPI_Bcast(&count, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD), "MPI_Bcast");
    const auto [counts, offsets] = slices(count, size_);
    const RecordType<Ray> ray_type;
    const RecordType<Hit> hit_type;
    const auto mine = static_cast<std::size_t>(counts[static_cast<std::size_t>(rank_)]);
    std::vector<Ray> slice(mine);
    check(MPI_Scatterv(rays.data(), counts.data(), offsets.data(), ray_type.get(), slice.data(),
                       static_cast<int>(mine), ray_type.get(), 0, MPI_COMM_WORLD),
          "MPI_Scatterv");
    std::vector<Hit> slice_hits(mine);
    on_every_rank("tracing the rays", [&] { intersect_parallel(accel, slice, slice_hits, threads); });
    std::vector<Hit> hits(rank_ == 0 ? count : 0);
    check(MPI_Gatherv(slice_hits.data(), static_cast<int>(mine), hit_type.get(), hits.data(), counts.data(),
                      offsets.data(), hit_type.get(), 0, MPI_COMM_WORLD),
          "MPI_Gatherv");
    return hits;
#else
    return {};
#endif
}

void Job::barrier() const {
#if LANCER_HAS_MPI
    if (!distributed()) return;
    // Polled with short sleeps, not MPI_Barrier: Open MPI spins a core in a blocking call, which would take
    // it from a rank still working on the same machine (bench --mpi times rank 0 alone while the others
    // wait here).
    MPI_Request request = MPI_REQUEST_NULL;
    check(MPI_Ibarrier(MPI_COMM_WORLD, &request), "MPI_Ibarrier");
    for (int done = 0;;) {
        check(MPI_Test(&request, &done, MPI_STATUS_IGNORE), "MPI_Test");
        if (done != 0) return;
        std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
#endif
}

double Job::max_over_ranks(double value) const {
#if LANCER_HAS_MPI
    if (distributed()) {
        double largest = value;
        check(MPI_Allreduce(&value, &largest, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD), "MPI_Allreduce");
        return largest;
    }
#endif
    return value;
}

}  // namespace lancer::cli
