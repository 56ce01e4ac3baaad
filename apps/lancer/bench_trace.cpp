#include "bench_trace.hpp"

#include <fmt/core.h>

#include <algorithm>
#include <optional>

#include "common.hpp"
#include "lancer/denormals.hpp"
#include "lancer/parallel.hpp"
#include "lancer/views.hpp"

namespace lancer::cli {
namespace {

// Rays are generated in square tiles of kTileSide x kTileSide pixels, one RayPacket each, and the tiles go in
// scanline order. PinholeCamera::tile_rays writes a tile's rays straight into the packet, every 16 lanes a
// 4x4 pixel block and every 8 a 4x2 one: the packets Embree's tutorials trace (embree8, embree16), and the
// packet structures' (bvh8_packet). Every structure gets the same packets; hits are stored and compared at
// their pixel.
constexpr int kTileSide = PinholeCamera::kTileSide;

int tile_rows(const PinholeCamera& camera) {
    return (camera.height() + kTileSide - 1) / kTileSide;
}

// Calls visit(x0, y0) for the corner of every tile of the tile rows [first_row, last_row), in scanline order.
template <class Visit>
void for_each_tile(const PinholeCamera& camera, int first_row, int last_row, Visit&& visit) {
    for (int tile_row = first_row; tile_row < last_row; ++tile_row) {
        for (int x0 = 0; x0 < camera.width(); x0 += kTileSide)
            visit(x0, tile_row * kTileSide);
    }
}

// Calls visit(lane, pixel) for every lane of the tile at (x0, y0) whose pixel lies in the image, pixel
// being its index in row-major order.
template <class Visit>
void for_each_tile_pixel(const PinholeCamera& camera, int x0, int y0, Visit&& visit) {
    const auto width = static_cast<std::size_t>(camera.width());
    for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
        const int i = x0 + PinholeCamera::tile_column(lane), j = y0 + PinholeCamera::tile_row(lane);
        if (i < camera.width() && j < camera.height())
            visit(lane, static_cast<std::size_t>(j) * width + static_cast<std::size_t>(i));
    }
}

// Each lane's hit at its pixel. A tile inside the image goes a block row at a time: 4 lanes, 4 pixels in a
// row of the image (HitPacket::copy_four).
void store_tile_hits(const PinholeCamera& camera, int x0, int y0, const HitPacket& tile_hits,
                     std::vector<Hit>& hits) {
    if (x0 + kTileSide > camera.width() || y0 + kTileSide > camera.height()) {
        for_each_tile_pixel(camera, x0, y0,
                            [&](int lane, std::size_t pixel) { hits[pixel] = tile_hits.hit(lane); });
        return;
    }
    const auto width = static_cast<std::size_t>(camera.width());
    for (int lane = 0; lane < RayPacket::kMaxSize; lane += PinholeCamera::kBlockSide) {
        Hit* const row = hits.data() + static_cast<std::size_t>(y0 + PinholeCamera::tile_row(lane)) * width +
                         static_cast<std::size_t>(x0 + PinholeCamera::tile_column(lane));
        tile_hits.copy_four(lane, row);
    }
}

// The tiles of the tile rows [first_row, last_row): each tile's rays generated into a packet, traced
// (Accel::intersect_packet), and each closest hit stored at its pixel of `hits`.
void trace_tiles(const Accel& accel, const PinholeCamera& camera, int first_row, int last_row,
                 std::vector<Hit>& hits, TraversalCounters* counters = nullptr) {
    RayPacket rays;
    HitPacket tile_hits;
    const auto width = static_cast<std::size_t>(camera.width());
    for_each_tile(camera, first_row, last_row, [&](int x0, int y0) {
        camera.tile_rays(x0, y0, rays);
        // The tile's pixels asked for, for writing, before the trace: the 64 hits are stored at once after
        // it, and the lines of a cold 16 MB image fetched then stalled the stores (Embree's tutorials store
        // each packet's hits as they come, which overlaps those fetches with the trace). Written here, not in
        // a function of its own: GCC deems a function of prefetches alone pure and drops its calls.
        // A tile row's 128 bytes may straddle three lines: every fourth pixel and the last are asked for.
        const int columns = std::min(kTileSide, camera.width() - x0);
        for (int row = 0; row < std::min(kTileSide, camera.height() - y0); ++row) {
            const Hit* const pixels =
                hits.data() + static_cast<std::size_t>(y0 + row) * width + static_cast<std::size_t>(x0);
            for (int column = 0; column < columns; column += 4)
                __builtin_prefetch(pixels + column, 1);
            __builtin_prefetch(pixels + columns - 1, 1);
        }
        accel.intersect_packet(rays, tile_hits, counters);
        store_tile_hits(camera, x0, y0, tile_hits, hits);
    });
}

}  // namespace

void trace_frame(const Accel& accel, const PinholeCamera& camera, std::vector<Hit>& hits) {
    const bool flush_denormals = accel.name().starts_with("embree");
    parallel_for(static_cast<std::size_t>(tile_rows(camera)), 1, 0, [&](std::size_t first, std::size_t last) {
        std::optional<DenormalsFlushed> flushed;
        if (flush_denormals) flushed.emplace();
        trace_tiles(accel, camera, static_cast<int>(first), static_cast<int>(last), hits);
    });
}

ViewAnswers answer_view(const Accel& accel, const ViewRays& view, const PinholeCamera& camera) {
    ViewAnswers answers;
    answers.hits.resize(view.rays.size());
    if (view.view == BenchView::Primary) {
        trace_tiles(accel, camera, 0, tile_rows(camera), answers.hits, &answers.counters);
    } else if (view.view == BenchView::Diffuse) {
        accel.intersect(view.rays, answers.hits, &answers.counters);
    } else {
        answers.occluded.resize(view.rays.size());
        accel.occluded(view.rays, answers.occluded, &answers.counters);
        answers.hit_count =
            static_cast<std::size_t>(std::count(answers.occluded.begin(), answers.occluded.end(), 1));
        return answers;
    }
    answers.hit_count = static_cast<std::size_t>(
        std::count_if(answers.hits.begin(), answers.hits.end(), [](const Hit& hit) { return hit.hit(); }));
    return answers;
}

std::vector<ViewRays> make_views(const std::vector<BenchView>& wanted, const Geometry& geometry,
                                 const PinholeCamera& camera, bool watertight) {
    const std::vector<Ray> primary = camera.pixel_centre_rays(0, 0, camera.width(), camera.height());
    std::vector<Hit> primary_hits;
    std::vector<ViewRays> views;
    for (BenchView view : wanted) {
        if (view == BenchView::Primary) {
            views.push_back({view, primary, {}, {}});
            continue;
        }
        if (primary_hits.empty()) {
            primary_hits.resize(primary.size());
            build_timed(AccelChoice{"bvh", watertight, {}}, geometry).accel->intersect(primary, primary_hits);
        }
        std::vector<Ray> rays =
            secondary_view_rays(view == BenchView::Diffuse ? SecondaryView::Diffuse : SecondaryView::Shadow,
                                geometry, primary, primary_hits);
        // No camera ray hit (a mesh seen edge on): nothing to time.
        if (rays.empty()) {
            fmt::print("bench: the {} view has no rays: no camera ray hits the mesh\n", view_name(view));
            continue;
        }
        views.push_back({view, std::move(rays), {}, {}});
    }
    return views;
}

}  // namespace lancer::cli
