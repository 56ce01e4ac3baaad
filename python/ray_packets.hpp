// cast_rays's way between NumPy's arrays and lancer's packets (docs/python.md, "Speed"). The (..., 6) rows
// go into RayPackets eight rays at a time, transposed in SIMD registers, through Accel::intersect_packet, and
// the answers into Open3D's five arrays eight at a time. Made field by field through `Ray` and `Hit` records,
// the same conversion cost as much as the trace.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
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

// The unit normal of each triangle, by global triangle index: three floats a triangle.
struct NormalTable {
    const float* xyz;
    std::size_t triangle_count;
};

// The answers of answer pair `pair`: a miss's ids kInvalidId and its uv and normal 0, a hit's normal from
// `normals`, its ids those of a scene of one geometry (geometry 0, primitive the global index). Returns which
// rays hit, as bits: 0 to 3 the pair's first group, 4 to 7 its second.
[[nodiscard]] unsigned store_pair(const HitPacket& hits, const PacketRows& where, std::size_t pair,
                                  const CastAnswers& answers, const NormalTable& normals);

// The answers of the packet's rays. In a scene of several geometries, each hit's geometry and primitive ids
// are `locate(global index)`'s pair.
template <class Locate>
void store_answers(const HitPacket& hits, const PacketRows& where, const CastAnswers& answers,
                   const NormalTable& normals, bool several_geometries, Locate&& locate) {
    for (std::size_t pair = 0; pair < where.answer_pairs.size(); ++pair) {
        unsigned hit_rays = store_pair(hits, where, pair, answers, normals);
        if (!several_geometries) continue;
        for (; hit_rays != 0; hit_rays &= hit_rays - 1) {
            const int bit = __builtin_ctz(hit_rays);
            const int group = where.answer_pairs[pair][static_cast<std::size_t>(bit / kGroupLanes)];
            const std::size_t row =
                where.row[static_cast<std::size_t>(group)] + static_cast<std::size_t>(bit % kGroupLanes);
            std::tie(answers.geometry_ids[row], answers.primitive_ids[row]) =
                locate(hits.prim[group * kGroupLanes + bit % kGroupLanes]);
        }
    }
}

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

  private:
    void image_chunk(std::size_t index, std::vector<PacketRows>& packets) const;
    void flat_chunk(std::size_t index, std::vector<PacketRows>& packets) const;

    std::size_t ray_count_ = 1;
    std::size_t height_ = 0, width_ = 0;  // of each image; width 0 for a flat array
    std::size_t bands_ = 0, segments_ = 0;
    std::size_t chunk_count_ = 0;
};

}  // namespace lancer::python
