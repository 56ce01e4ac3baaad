// cast_rays's way between NumPy's arrays and lancer's packets (docs/python.md, "Speed"). The (..., 6) rows
// go into RayPackets eight rays at a time, transposed in SIMD registers, through Accel::intersect_packet, and
// the answers into Open3D's five arrays eight at a time, streamed for pairs of camera tiles. Made
// field by field through `Ray` and `Hit` records, the same conversion cost as much as the trace.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "lancer/packet.hpp"
#include "lancer/ray.hpp"

namespace lancer::python {

// Open3D's RaycastingScene.INVALID_ID: the geometry and primitive id of a miss.
inline constexpr std::uint32_t kInvalidId = 0xFFFFFFFFu;

// A packet is sixteen groups of four lanes, lanes 4g to 4g + 3, each four consecutive rows of the array: a
// row of a 4x4 pixel block of a camera tile (PinholeCamera::tile_rays's order), or four of 64 consecutive
// rays.
inline constexpr int kGroupLanes = 4;
inline constexpr int kGroups = RayPacket::kMaxSize / kGroupLanes;

// Where a packet's rays come from, and their answers go: group g is rows row[g] to row[g] + count[g] - 1 of
// the (..., 6) array (count 0 to 4; the lanes beyond get rays that miss). The groups are also paired by
// their answers, answer_pairs[k] = {a, b} with row[b] == row[a] + 4: eight neighbours in the array, whose
// answers are stored together.
struct PacketRows {
    std::array<std::size_t, kGroups> row{};
    std::array<int, kGroups> count{};
    std::array<std::array<int, 2>, kGroups / 2> answer_pairs{};
};

// Open3D's five answers of cast_rays, NumPy's arrays, by row.
struct CastAnswers {
    float* t_hit;
    std::uint32_t* geometry_ids;
    std::uint32_t* primitive_ids;
    float* uvs;      // two a ray
    float* normals;  // three a ray
};

// The packet's rays from `rows` (6 floats a ray), with the interval [0, inf). Returns false when one of them
// holds a NaN or an infinity (first_bad_row says which).
[[nodiscard]] bool load_rays(const float* rows, const PacketRows& where, RayPacket& rays);
// The first row of the packet holding a NaN or an infinity.
[[nodiscard]] std::size_t first_bad_row(const float* rows, const PacketRows& where);

// The rays of `packets` as `Ray` records for one Accel::intersect batch call, RayPacket::kMaxSize a packet
// in its lane order (lanes without a row get a ray of zero direction, which misses), with the interval
// [0, inf): the batch call is where a structure regroups rays its packets cannot trace together. Returns the
// index of the first packet holding a NaN or an infinity, or packets.size().
[[nodiscard]] std::size_t load_ray_records(const float* rows, std::span<const PacketRows> packets,
                                           std::vector<Ray>& rays);
// Packet `packet`'s lanes of the batch's `Hit` records.
void gather_hits(std::span<const Hit> hits, std::size_t packet, HitPacket& out);

// Asks for the lines the packet's answers go to, for writing: called before the trace, it overlaps their
// fetch with the trace instead of stalling the stores after it.
void prefetch_answers(const PacketRows& where, const CastAnswers& answers);

// The unit normal of each triangle, three floats a triangle: triangle p's at xyz + 3p, for p from -1 (a
// miss's index, whose normal is 0) to the last triangle, then one more float, which the answers' 4-float
// loads may read.
struct NormalTable {
    const float* xyz;
};

// Where each geometry's triangles start in the global triangle index, increasing, then their total.
struct GeometryStarts {
    std::span<const std::uint32_t> first;  // one more than the geometries

    [[nodiscard]] std::size_t geometry_count() const { return first.size() - 1; }
    // The geometry and primitive ids of global triangle index `prim`: the last geometry starting at or
    // before it, and its index from that start.
    [[nodiscard]] std::pair<std::uint32_t, std::uint32_t> locate(std::int32_t prim) const;
    // locate, trying geometry `geometry` (below geometry_count()) before searching, and leaving the answer's
    // geometry in it.
    [[nodiscard]] std::pair<std::uint32_t, std::uint32_t> locate(std::int32_t prim,
                                                                 std::uint32_t& geometry) const;
};

// What the answers of a hit need from the scene beside the trace: its normal and its ids.
struct HitTables {
    NormalTable normals;
    GeometryStarts geometries;
};

// The answers of the packet's rays, by answer pair: a miss's ids kInvalidId and its uv and normal 0, a
// hit's normal and ids from `tables`.
void store_pairs(const HitPacket& hits, const PacketRows& where, const CastAnswers& answers,
                 const HitTables& tables);

// store_pairs's answers of two whole camera tiles side by side (RayChunks::tile_pair), streamed into the
// arrays with non-temporal stores. Each image row's sixteen answers fill whole lines of every array, each
// written whole before the next is begun, so that no line is fetched for ownership first as the stores of a
// tile alone, 32 bytes of `t` in each of eight rows, need; those fetches were most of the answers' cost
// (docs/python.md, "Speed"). The arrays must start on 64-byte boundaries (lines_aligned).
void stream_tile_pair(const HitPacket& left_hits, const HitPacket& right_hits, const PacketRows& left,
                      const PacketRows& right, const CastAnswers& answers, const HitTables& tables);

// Whether the five arrays start on 64-byte boundaries, as stream_tile_pair needs.
[[nodiscard]] bool lines_aligned(const CastAnswers& answers);

// Makes the thread's non-temporal stores (stream_tile_pair) visible before what it does next, such as ending
// its task: they are weakly ordered, unlike the other stores.
void finish_streamed_stores();

// The chunks of a cast_rays call, each kChunkPackets packets or fewer, traced by one task. An array whose
// last two leading axes are both 8 or more holds images (rows and columns, the axes before them numbering
// the images) and goes by camera tiles, 8 x 8 rays in PinholeCamera::tile_rays's lane order, which the packet
// kernels trace fastest: a chunk is a band of eight rows, kChunkPackets tiles wide. Any other goes by
// packets of 64 consecutive rays.
class RayChunks {
  public:
    static constexpr std::size_t kChunkPackets = 64;  // 4096 rays, one batch call

    // `shape`: the array's leading shape, its last axis (6) left out.
    explicit RayChunks(std::span<const std::size_t> shape);
    [[nodiscard]] std::size_t size() const { return chunk_count_; }
    [[nodiscard]] bool images() const { return width_ != 0; }
    // The packets of chunk `index`.
    void chunk(std::size_t index, std::vector<PacketRows>& packets) const;
    // Whether packets `left` and `right`, consecutive in a chunk, are two camera tiles side by side, all
    // their rays in an image whose width is a multiple of 16, the first's columns starting at a multiple of
    // 16: the pairs stream_tile_pair streams. A flat array's packets are none: their answers go to
    // consecutive lines already, and streamed they were slower (docs/python.md).
    [[nodiscard]] bool tile_pair(const PacketRows& left, const PacketRows& right) const;

  private:
    void image_chunk(std::size_t index, std::vector<PacketRows>& packets) const;
    void flat_chunk(std::size_t index, std::vector<PacketRows>& packets) const;

    std::size_t ray_count_ = 1;
    std::size_t height_ = 0, width_ = 0;  // of each image; width 0 for a flat array
    std::size_t bands_ = 0, segments_ = 0;
    std::size_t chunk_count_ = 0;
};

// Traces and answers a chunk's packets: trace(where, hits) traces the packet `where`. Tile pairs are
// streamed when the arrays start on 64-byte boundaries, any other packet answered in place.
template <class Trace>
void answer_chunk(const RayChunks& chunks, std::span<const PacketRows> packets, const CastAnswers& answers,
                  const HitTables& tables, Trace&& trace) {
    HitPacket hits, right_hits;
    const bool stream_pairs = lines_aligned(answers);
    for (std::size_t i = 0; i < packets.size();) {
        if (stream_pairs && i + 1 < packets.size() && chunks.tile_pair(packets[i], packets[i + 1])) {
            trace(packets[i], hits);
            trace(packets[i + 1], right_hits);
            stream_tile_pair(hits, right_hits, packets[i], packets[i + 1], answers, tables);
            i += 2;
        } else {
            prefetch_answers(packets[i], answers);
            trace(packets[i], hits);
            store_pairs(hits, packets[i], answers, tables);
            ++i;
        }
    }
    finish_streamed_stores();
}

}  // namespace lancer::python
