// cast_rays's way between NumPy's arrays and lancer's packets (docs/python.md, "Speed"). The (..., 6) rows
// go into RayPackets eight rays at a time, transposed in SIMD registers, through Accel::intersect_packet, and
// the answers into Open3D's five arrays eight at a time, through a stage for pairs of camera tiles. Made
// field by field through `Ray` and `Hit` records, the same conversion cost as much as the trace.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <tuple>
#include <vector>

#include "lancer/packet.hpp"

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

// Asks for the lines the packet's answers go to, for writing: called before the trace, it overlaps their
// fetch with the trace instead of stalling the stores after it.
void prefetch_answers(const PacketRows& where, const CastAnswers& answers);

// The unit normal of each triangle, three floats a triangle: triangle p's at xyz + 3p, for p from -1 (a
// miss's index, whose normal is 0) to triangle_count - 1, then one more float, which the answers' 4-float
// loads may read.
struct NormalTable {
    const float* xyz;
    std::size_t triangle_count;
};

// The answers of each answer pair: a miss's ids kInvalidId and its uv and normal 0, a hit's normal from
// `normals`, its ids those of a scene of one geometry (geometry 0, primitive the global index). hit_rays[k]
// says which rays of pair k hit, as bits: 0 to 3 the pair's first group, 4 to 7 its second.
void store_pairs(const HitPacket& hits, const PacketRows& where, const CastAnswers& answers,
                 const NormalTable& normals, std::array<unsigned, kGroups / 2>& hit_rays);

// The answers of the packet's rays. In a scene of several geometries, each hit's geometry and primitive ids
// are `locate(global index)`'s pair.
template <class Locate>
void store_answers(const HitPacket& hits, const PacketRows& where, const CastAnswers& answers,
                   const NormalTable& normals, bool several_geometries, Locate&& locate) {
    std::array<unsigned, kGroups / 2> hit_rays;
    store_pairs(hits, where, answers, normals, hit_rays);
    if (!several_geometries) return;
    for (std::size_t pair = 0; pair < hit_rays.size(); ++pair) {
        for (unsigned rays = hit_rays[pair]; rays != 0; rays &= rays - 1) {
            const int bit = __builtin_ctz(rays);
            const int group = where.answer_pairs[pair][static_cast<std::size_t>(bit / kGroupLanes)];
            const std::size_t row =
                where.row[static_cast<std::size_t>(group)] + static_cast<std::size_t>(bit % kGroupLanes);
            std::tie(answers.geometry_ids[row], answers.primitive_ids[row]) =
                locate(hits.prim[group * kGroupLanes + bit % kGroupLanes]);
        }
    }
}

// Two camera tiles side by side, whose answers fill whole cache lines in each of the five arrays: kRows image
// rows of kRowRays rays, row k from ray first + k * stride (the image's width), each row's first ray a
// multiple of kRowRays, so that every row starts a line when the arrays start on a 64-byte boundary.
struct AnswerBlock {
    static constexpr std::size_t kRows = 8, kRowRays = 16;
    std::size_t first = 0, stride = 0;
};

// The answers of an answer block, written first into a stage that stays in L1, then into the arrays with
// non-temporal stores, a whole line at a time. Written in place, each line is first fetched for ownership,
// and a camera tile's answers touch eight rows of each array: those fetches cost more than the stage's
// extra pass (docs/python.md, "Speed").
class StagedAnswers {
  public:
    StagedAnswers();
    // The stage's arrays, which store_answers writes through `rebase(where)`.
    [[nodiscard]] const CastAnswers& view() const { return view_; }
    // `where`, one of the block's packets, with its rows numbered in the stage.
    [[nodiscard]] PacketRows rebase(const PacketRows& where, const AnswerBlock& block) const;
    // The stage into the block's rows of `answers`, whose five arrays start on 64-byte boundaries.
    void write_out(const CastAnswers& answers, const AnswerBlock& block) const;

  private:
    static constexpr std::size_t kRays = AnswerBlock::kRows * AnswerBlock::kRowRays;
    alignas(64) float t_hit_[kRays];
    alignas(64) std::uint32_t geometry_ids_[kRays];
    alignas(64) std::uint32_t primitive_ids_[kRays];
    alignas(64) float uvs_[2 * kRays];
    alignas(64) float normals_[3 * kRays];
    CastAnswers view_;
};

// Makes the thread's non-temporal stores (StagedAnswers::write_out) visible before what it does next, such as
// ending its task: they are weakly ordered, unlike the other stores.
void finish_streamed_stores();

// Whether the five arrays start on 64-byte boundaries, as StagedAnswers::write_out needs.
[[nodiscard]] bool lines_aligned(const CastAnswers& answers);

// The chunks of a cast_rays call, each kChunkPackets packets or fewer, traced by one task. An array whose
// last two leading axes are both 8 or more holds images (rows and columns, the axes before them numbering
// the images) and goes by camera tiles, 8 x 8 rays in PinholeCamera::tile_rays's lane order, which the packet
// kernels trace fastest: a chunk is a band of eight rows, kChunkPackets tiles wide. Any other goes by
// packets of 64 consecutive rays.
class RayChunks {
  public:
    static constexpr std::size_t kChunkPackets = 32;

    // `shape`: the array's leading shape, its last axis (6) left out.
    explicit RayChunks(std::span<const std::size_t> shape);
    [[nodiscard]] std::size_t size() const { return chunk_count_; }
    [[nodiscard]] bool images() const { return width_ != 0; }
    // The packets of chunk `index`.
    void chunk(std::size_t index, std::vector<PacketRows>& packets) const;
    // The answer block of packets `left` and `right`, consecutive in a chunk, when they make one: two camera
    // tiles side by side, all their rays in the image, in an image whose width is a multiple of 16. A flat
    // array's packets make none: their answers go straight to consecutive lines, which was measured faster
    // than staging them (docs/python.md).
    [[nodiscard]] std::optional<AnswerBlock> answer_block(const PacketRows& left,
                                                          const PacketRows& right) const;

  private:
    void image_chunk(std::size_t index, std::vector<PacketRows>& packets) const;
    void flat_chunk(std::size_t index, std::vector<PacketRows>& packets) const;

    std::size_t ray_count_ = 1;
    std::size_t height_ = 0, width_ = 0;  // of each image; width 0 for a flat array
    std::size_t bands_ = 0, segments_ = 0;
    std::size_t chunk_count_ = 0;
};

// Traces and answers a chunk's packets: trace(where, hits) traces the packet `where`. Two packets that make
// an answer block go through a StagedAnswers when the arrays start on 64-byte boundaries, any other packet
// straight into the arrays. In a scene of several geometries, locate names each hit (store_answers).
template <class Trace, class Locate>
void answer_chunk(const RayChunks& chunks, std::span<const PacketRows> packets, const CastAnswers& answers,
                  const NormalTable& normals, bool several_geometries, Trace&& trace, Locate&& locate) {
    HitPacket hits;
    StagedAnswers stage;
    const bool stage_blocks = lines_aligned(answers);
    for (std::size_t i = 0; i < packets.size();) {
        const std::optional<AnswerBlock> block = stage_blocks && i + 1 < packets.size()
                                                     ? chunks.answer_block(packets[i], packets[i + 1])
                                                     : std::nullopt;
        if (block) {
            for (const std::size_t k : {i, i + 1}) {
                trace(packets[k], hits);
                store_answers(hits, stage.rebase(packets[k], *block), stage.view(), normals,
                              several_geometries, locate);
            }
            stage.write_out(answers, *block);
            i += 2;
        } else {
            prefetch_answers(packets[i], answers);
            trace(packets[i], hits);
            store_answers(hits, packets[i], answers, normals, several_geometries, locate);
            ++i;
        }
    }
    finish_streamed_stores();
}

}  // namespace lancer::python
