// The triangle block kernels of the wide BVH (src/accel/bvh/triangle_block.hpp) against the scalar loop they
// replace, and the wide BVHs beside Embree on the canonical view of the Stanford meshes. Google Benchmark
// reports CPU time, which a machine shared with other work disturbs less than the wall clock of `lancer
// bench`.
//   build/bench/lancer_block_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "accel/bvh/triangle_block.hpp"
#include "lancer/accel.hpp"
#include "lancer/camera.hpp"
#include "lancer/denormals.hpp"
#include "lancer/load_scene.hpp"

namespace lancer {
namespace {

constexpr std::size_t kBlocks = 1024;

// kBlocks blocks of K random triangles in [-1, 1]^3 and one ray per block aimed at the centre of one of its
// triangles, so that most blocks have a hit and the closest-hit selection runs.
template <int K>
struct BlockInputs {
    std::vector<Triangle> triangles;
    std::vector<std::uint32_t> prims;
    std::vector<TriangleBlock<K>> blocks;
    std::vector<Ray> rays;

    BlockInputs() {
        std::mt19937 rng(42);
        std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
        std::uniform_int_distribution<int> lane(0, K - 1);
        auto point = [&] { return Vec3f(coordinate(rng), coordinate(rng), coordinate(rng)); };
        for (std::size_t i = 0; i < kBlocks * K; ++i) {
            triangles.push_back({point(), point(), point()});
            prims.push_back(static_cast<std::uint32_t>(i));
        }
        const Geometry geometry{triangles, {}};
        for (std::size_t b = 0; b < kBlocks; ++b) {
            append_leaf_blocks(geometry, std::span(prims).subspan(b * K, K), blocks);
            const Vec3f origin = point() * 4.0f;
            rays.push_back(
                {origin, triangles[b * K + lane(rng)].bounds().center() - origin, 0.0f, kInfinity});
        }
    }
};

// One leaf of K triangles per iteration: the block kernel (kBlock) or the scalar loop it replaces.
template <class TriangleTestT, int K, bool kBlock>
void BM_Leaf(benchmark::State& state) {
    static const BlockInputs<K> in;
    const Geometry geometry{in.triangles, {}};
    std::size_t b = 0;
    for (auto _ : state) {
        const PreparedRay<TriangleTestT> prepared(in.rays[b]);
        Hit best;
        if constexpr (kBlock) {
            intersect_block(geometry, in.blocks[b], BlockRay<TriangleTestT, K>(prepared, geometry), best);
        } else {
            for (std::size_t i = b * K; i < (b + 1) * K; ++i)
                intersect_primitive(geometry, static_cast<std::uint32_t>(i), prepared, best);
        }
        benchmark::DoNotOptimize(best);
        b = (b + 1) % kBlocks;
    }
    state.SetItemsProcessed(state.iterations() * K);
}

BENCHMARK(BM_Leaf<MollerTrumbore, 4, true>)->Name("block4/moller_trumbore");
BENCHMARK(BM_Leaf<MollerTrumbore, 4, false>)->Name("scalar4/moller_trumbore");
BENCHMARK(BM_Leaf<Watertight, 4, true>)->Name("block4/watertight");
BENCHMARK(BM_Leaf<Watertight, 4, false>)->Name("scalar4/watertight");
BENCHMARK(BM_Leaf<MollerTrumbore, 8, true>)->Name("block8/moller_trumbore");
BENCHMARK(BM_Leaf<MollerTrumbore, 8, false>)->Name("scalar8/moller_trumbore");
BENCHMARK(BM_Leaf<Watertight, 8, true>)->Name("block8/watertight");
BENCHMARK(BM_Leaf<Watertight, 8, false>)->Name("scalar8/watertight");

// A Stanford mesh of the shared data, loaded once; nullptr when the shared data is absent.
const SceneGeometry* stanford_mesh(const std::string& file) {
    struct Loaded {
        Scene scene;
        std::unique_ptr<SceneGeometry> geometry;
    };
    static std::map<std::string, Loaded> meshes;
    const std::filesystem::path path = std::filesystem::path(LANCER_SHARED_DIR) / "data/meshes" / file;
    if (!std::filesystem::exists(path)) return nullptr;
    Loaded& loaded = meshes[file];
    if (!loaded.geometry) {
        loaded.scene = load_scene(path);
        loaded.geometry = std::make_unique<SceneGeometry>(loaded.scene);
    }
    return loaded.geometry.get();
}

// The canonical view (VIEWS.md) of a Stanford mesh at 512 x 512, one triangle test, one thread: rays per
// second of CPU time. The rays are made once, one RayPacket per 8x8 tile (PinholeCamera::tile_rays), and
// traced through Accel::intersect_packet, the call the packet structures and Embree's packet calls are
// fastest on.
void BM_CanonicalView(benchmark::State& state, const char* mesh, const char* accel_name, TriangleTest test) {
    const SceneGeometry* geometry = stanford_mesh(mesh);
    if (geometry == nullptr) {
        state.SkipWithError("no shared data");
        return;
    }
    const PinholeCamera camera(canonical_view(geometry->view().bounds(), 512, 512));
    constexpr int kTile = PinholeCamera::kTileSide;
    std::vector<RayPacket> packets;
    for (int tile_y = 0; tile_y < camera.height(); tile_y += kTile) {
        for (int tile_x = 0; tile_x < camera.width(); tile_x += kTile)
            camera.tile_rays(tile_x, tile_y, packets.emplace_back());
    }
    std::unique_ptr<Accel> accel = make_accel(accel_name);
    accel->build(geometry->view(), build_options(test));
    std::vector<HitPacket> hits(packets.size());
    // Embree's rows with flush-to-zero set once, as its manual asks (lancer/denormals.hpp).
    std::optional<DenormalsFlushed> flushed;
    if (std::string_view(accel_name).starts_with("embree")) flushed.emplace();
    for (auto _ : state) {
        for (std::size_t i = 0; i < packets.size(); ++i)
            accel->intersect_packet(packets[i], hits[i]);
        benchmark::DoNotOptimize(hits.data());
    }
    state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(packets.size()) *
                            RayPacket::kMaxSize);
}

const bool canonical_views_registered = [] {
    for (const char* mesh : {"bunny.obj", "armadillo.off", "dragon.ply"}) {
        for (const char* accel : {"bvh4", "bvh8", "bvh8_packet", "embree", "embree16"}) {
            for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
                const char* test_name = test == TriangleTest::Watertight ? "/watertight" : "/moller_trumbore";
                benchmark::RegisterBenchmark((std::string(mesh) + "/" + accel + test_name).c_str(),
                                             BM_CanonicalView, mesh, accel, test)
                    ->Unit(benchmark::kMillisecond);
            }
        }
    }
    return true;
}();

}  // namespace
}  // namespace lancer
