// cast_rays's answers (python/ray_packets.hpp) without Python and without the trace: a 1024 x 1024 image of
// camera tiles answered into Open3D's five arrays (32 MB, as in the canonical view) in place (store_pairs,
// with the write prefetches cast_rays asks for) or streamed a tile pair at a time (stream_tile_pair). The
// tiles' hits cycle through a pool of 256 packets, which stays in the caches as a packet just traced does. A
// fraction of the rays hit (the first argument, in percent), in runs along the rows as a mesh's silhouette
// makes them, in a scene of one geometry or of 64. Google Benchmark reports CPU time (docs/python.md,
// "Speed").
//   build/bench/lancer_answers_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cstdint>
#include <new>
#include <random>
#include <vector>

#include "ray_packets.hpp"

namespace lancer::python {
namespace {

constexpr std::size_t kWidth = 1024, kRows = 1024, kPool = 256, kTriangles = 69451;  // the bunny's triangles

// A 64-byte aligned array of `count` values, freed with it.
template <class T>
struct LineArray {
    explicit LineArray(std::size_t count)
        : data(static_cast<T*>(::operator new (count * sizeof(T), std::align_val_t{64}))) {}
    ~LineArray() { ::operator delete (data, std::align_val_t{64}); }
    LineArray(const LineArray&) = delete;
    LineArray& operator=(const LineArray&) = delete;
    T* data;
};

struct Image {
    LineArray<float> t_hit{kWidth * kRows}, uvs{2 * kWidth * kRows}, normals{3 * kWidth * kRows};
    LineArray<std::uint32_t> geometry_ids{kWidth * kRows}, primitive_ids{kWidth * kRows};
    std::vector<float> normal_table = std::vector<float>(3 * kTriangles + 4, 0.5f);
    std::vector<std::uint32_t> starts;
    std::vector<PacketRows> tiles;
    std::vector<HitPacket> hits;

    Image(int hit_percent, std::uint32_t geometries) {
        std::fill_n(normal_table.begin(), 3, 0.0f);
        for (std::uint32_t g = 0; g <= geometries; ++g)
            starts.push_back(static_cast<std::uint32_t>(std::uint64_t{kTriangles} * g / geometries));
        const RayChunks chunks(std::vector<std::size_t>{kRows, kWidth});
        std::vector<PacketRows> chunk;
        for (std::size_t index = 0; index < chunks.size(); ++index) {
            chunks.chunk(index, chunk);
            tiles.insert(tiles.end(), chunk.begin(), chunk.end());
        }
        // Runs of 1 to 16 hits or misses along the rows of the pool's tiles, their lengths drawn to give
        // hit_percent overall.
        std::mt19937 rng(7);
        std::uniform_int_distribution<int> run(1, 16), percent(0, 99), triangle(0, kTriangles - 1);
        std::vector<Hit> by_ray(kPool * RayPacket::kMaxSize);
        for (std::size_t ray = 0; ray < by_ray.size();) {
            const bool hit = percent(rng) < hit_percent;
            const int first = triangle(rng);
            for (int k = run(rng); k > 0 && ray < by_ray.size(); --k, ++ray) {
                if (hit) by_ray[ray] = Hit{1.0f, (first + k) % static_cast<int>(kTriangles), 0.25f, 0.5f};
            }
        }
        hits.resize(kPool);
        for (std::size_t lane = 0; lane < by_ray.size(); ++lane)
            hits[lane / RayPacket::kMaxSize].set(static_cast<int>(lane % RayPacket::kMaxSize), by_ray[lane]);
    }
    CastAnswers answers() const {
        return {t_hit.data, geometry_ids.data, primitive_ids.data, uvs.data, normals.data};
    }
    HitTables tables() const { return {NormalTable{normal_table.data() + 3}, GeometryStarts{starts}}; }
};

template <bool kStreamed>
void BM_Answers(benchmark::State& state) {
    const Image image(static_cast<int>(state.range(0)), static_cast<std::uint32_t>(state.range(1)));
    const CastAnswers answers = image.answers();
    const HitTables tables = image.tables();
    const auto hits = [&](std::size_t tile) -> const HitPacket& { return image.hits[tile % kPool]; };
    for (auto _ : state) {
        for (std::size_t i = 0; i + 1 < image.tiles.size(); i += 2) {
            if constexpr (kStreamed) {
                stream_tile_pair(hits(i), hits(i + 1), image.tiles[i], image.tiles[i + 1], answers, tables);
            } else {
                for (const std::size_t k : {i, i + 1}) {
                    prefetch_answers(image.tiles[k], answers);
                    store_pairs(hits(k), image.tiles[k], answers, tables);
                }
            }
        }
        finish_streamed_stores();
        benchmark::ClobberMemory();
    }
    state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(kWidth * kRows));
}

void hit_fractions(benchmark::internal::Benchmark* bench) {
    for (const int geometries : {1, 64}) {
        for (const int hit_percent : {0, 20, 100})
            bench->Args({hit_percent, geometries});
    }
    bench->ArgNames({"hit_percent", "geometries"});
}

BENCHMARK(BM_Answers<false>)->Name("in_place")->Apply(hit_fractions);
BENCHMARK(BM_Answers<true>)->Name("streamed")->Apply(hit_fractions);

}  // namespace
}  // namespace lancer::python
