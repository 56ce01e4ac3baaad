#include "ray_packets.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <tuple>
#include <utility>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "lancer/camera.hpp"

namespace lancer::python {
namespace {

constexpr int kFields = 6;  // a ray's row: origin, then direction

// Lane `lane` from `row`, or a ray of zero direction, which misses (is_valid), when `row` is null.
void set_lane(RayPacket& rays, int lane, const float* row) {
    for (int axis = 0; axis < 3; ++axis) {
        rays.origin[axis][lane] = row != nullptr ? row[axis] : 0.0f;
        rays.direction[axis][lane] = row != nullptr ? row[3 + axis] : 0.0f;
    }
}

bool finite_row(const float* row) {
    bool finite = true;
    for (int k = 0; k < kFields; ++k)
        finite &= std::isfinite(row[k]);
    return finite;
}

#if defined(__AVX2__)
// Whether every lane of `x` is finite: |x| < inf is false for a NaN and an infinity.
__m256 finite_lanes(__m256 x) {
    return _mm256_cmp_ps(_mm256_andnot_ps(_mm256_set1_ps(-0.0f), x), _mm256_set1_ps(kInfinity), _CMP_LT_OQ);
}

// Lanes [lane, lane + 8) in one store per field, which the kernel's loads of eight lanes then read whole:
// four rays from `low` in the low half of each register, four from `high` in the high half. The first four
// floats of a ray (ox oy oz dx) make a 4x4 matrix per half, and so do its last four (oz dx dy dz): two
// transposes give the six fields. Returns whether all of them are finite.
bool load_eight(const float* low, const float* high, RayPacket& rays, int lane) {
    __m256 head[kGroupLanes], tail[kGroupLanes];
    for (int k = 0; k < kGroupLanes; ++k) {
        head[k] = _mm256_loadu2_m128(high + kFields * k, low + kFields * k);
        tail[k] = _mm256_loadu2_m128(high + kFields * k + 2, low + kFields * k + 2);
    }
    const __m256 ab_low = _mm256_unpacklo_ps(head[0], head[1]),
                 ab_high = _mm256_unpackhi_ps(head[0], head[1]);
    const __m256 cd_low = _mm256_unpacklo_ps(head[2], head[3]),
                 cd_high = _mm256_unpackhi_ps(head[2], head[3]);
    const __m256 ab_tail = _mm256_unpackhi_ps(tail[0], tail[1]),
                 cd_tail = _mm256_unpackhi_ps(tail[2], tail[3]);
    const __m256 fields[kFields] = {
        _mm256_shuffle_ps(ab_low, cd_low, 0x44),   _mm256_shuffle_ps(ab_low, cd_low, 0xEE),
        _mm256_shuffle_ps(ab_high, cd_high, 0x44), _mm256_shuffle_ps(ab_high, cd_high, 0xEE),
        _mm256_shuffle_ps(ab_tail, cd_tail, 0x44), _mm256_shuffle_ps(ab_tail, cd_tail, 0xEE)};
    __m256 finite = finite_lanes(fields[0]);
    for (int axis = 0; axis < 3; ++axis) {
        _mm256_store_ps(rays.origin[axis] + lane, fields[axis]);
        _mm256_store_ps(rays.direction[axis] + lane, fields[3 + axis]);
        finite =
            _mm256_and_ps(finite, _mm256_and_ps(finite_lanes(fields[axis]), finite_lanes(fields[3 + axis])));
    }
    return _mm256_movemask_ps(finite) == 0xFF;
}

// The normals of four rays, whose global triangle indices start at `prim`, as their rows hold them: twelve
// floats, x y z a ray, in three registers. A ray's normal is one unaligned 4-float load from the table (a
// miss's, index -1, the table's zero entry); the loads' fourth floats are dropped by the shuffles.
void four_normals(const std::int32_t* prim, const NormalTable& normals, __m128* out) {
    __m128 ray[kGroupLanes];
    for (int k = 0; k < kGroupLanes; ++k)
        ray[k] = _mm_loadu_ps(normals.xyz + 3 * static_cast<std::ptrdiff_t>(prim[k]));
    // [x0 y0 z0 x1], [y1 z1 x2 y2], [z2 x3 y3 z3]
    out[0] = _mm_blend_ps(ray[0], _mm_shuffle_ps(ray[1], ray[1], _MM_SHUFFLE(0, 0, 0, 0)), 0b1000);
    out[1] = _mm_shuffle_ps(ray[1], ray[2], _MM_SHUFFLE(1, 0, 2, 1));
    out[2] = _mm_blend_ps(_mm_castsi128_ps(_mm_slli_si128(_mm_castps_si128(ray[3]), 4)),
                          _mm_shuffle_ps(ray[2], ray[2], _MM_SHUFFLE(2, 2, 2, 2)), 0b0001);
}

// The ids of a pair's hits in a scene of several geometries, from their global indices: the misses' lanes
// keep theirs. Neighbouring rays mostly hit one geometry, so each hit tries the previous hit's first.
void locate_hits(const GeometryStarts& geometries, unsigned hit_rays, __m256i& geometry, __m256i& primitive) {
    alignas(32) std::uint32_t geometry_ids[8], primitive_ids[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(geometry_ids), geometry);
    _mm256_store_si256(reinterpret_cast<__m256i*>(primitive_ids), primitive);
    std::uint32_t last_geometry = 0;
    for (; hit_rays != 0; hit_rays &= hit_rays - 1) {
        const int lane = __builtin_ctz(hit_rays);
        std::tie(geometry_ids[lane], primitive_ids[lane]) =
            geometries.locate(static_cast<std::int32_t>(primitive_ids[lane]), last_geometry);
    }
    geometry = _mm256_load_si256(reinterpret_cast<const __m256i*>(geometry_ids));
    primitive = _mm256_load_si256(reinterpret_cast<const __m256i*>(primitive_ids));
}

// The answers of eight neighbouring rays, a pair of full groups (lanes low_lane to low_lane + 3, then
// high_lane to high_lane + 3), in registers as the arrays lay them out.
struct EightAnswers {
    __m256 t;
    __m256i geometry, primitive;
    __m256 uv[2];      // u v of rays 0-3, then of rays 4-7
    __m128 normal[6];  // x y z of rays 0-3 in the first three, of rays 4-7 in the last three

    EightAnswers(const HitPacket& hits, int low_lane, int high_lane, const HitTables& tables) {
        const auto lanes_of = [&](const auto* field) {
            return _mm256_loadu2_m128(reinterpret_cast<const float*>(field + high_lane),
                                      reinterpret_cast<const float*>(field + low_lane));
        };
        t = lanes_of(hits.t);
        primitive = _mm256_castps_si256(lanes_of(hits.prim));
        const __m256i hit = _mm256_cmpgt_epi32(primitive, _mm256_set1_epi32(-1));
        const __m256 hit_mask = _mm256_castsi256_ps(hit);
        const auto hit_rays = static_cast<unsigned>(_mm256_movemask_ps(hit_mask));
        // A miss's prim is -1, whose bits are kInvalidId; a hit's ids in a scene of one geometry are 0 and
        // prim.
        geometry = _mm256_andnot_si256(hit, primitive);
        if (tables.geometries.geometry_count() > 1 && hit_rays != 0)
            locate_hits(tables.geometries, hit_rays, geometry, primitive);
        const __m256 u = _mm256_and_ps(hit_mask, lanes_of(hits.u));
        const __m256 v = _mm256_and_ps(hit_mask, lanes_of(hits.v));
        const __m256 uv_low = _mm256_unpacklo_ps(u, v), uv_high = _mm256_unpackhi_ps(u, v);
        uv[0] = _mm256_permute2f128_ps(uv_low, uv_high, 0x20);
        uv[1] = _mm256_permute2f128_ps(uv_low, uv_high, 0x31);
        if (hit_rays != 0) {
            four_normals(hits.prim + low_lane, tables.normals, normal);
            four_normals(hits.prim + high_lane, tables.normals, normal + 3);
        } else {
            std::fill(std::begin(normal), std::end(normal), _mm_setzero_ps());
        }
    }

    // Into rows [row, row + 8) of the arrays, in place.
    void store(const CastAnswers& answers, std::size_t row) const {
        _mm256_storeu_ps(answers.t_hit + row, t);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(answers.geometry_ids + row), geometry);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(answers.primitive_ids + row), primitive);
        _mm256_storeu_ps(answers.uvs + 2 * row, uv[0]);
        _mm256_storeu_ps(answers.uvs + 2 * row + 8, uv[1]);
        for (int k = 0; k < 6; ++k)
            _mm_storeu_ps(answers.normals + 3 * row + 4 * k, normal[k]);
    }
};

// The answers of sixteen rays from `row`, a multiple of 16, `left`'s then `right`'s: whole lines of every
// array, streamed one line after the other, so that no line is left half written while the next is begun
// (stream_tile_pair).
void stream_sixteen(const EightAnswers& left, const EightAnswers& right, const CastAnswers& answers,
                    std::size_t row) {
    const auto stream_ids = [](std::uint32_t* to, __m256i ids) {
        _mm256_stream_si256(reinterpret_cast<__m256i*>(to), ids);
    };
    _mm256_stream_ps(answers.t_hit + row, left.t);
    _mm256_stream_ps(answers.t_hit + row + 8, right.t);
    stream_ids(answers.geometry_ids + row, left.geometry);
    stream_ids(answers.geometry_ids + row + 8, right.geometry);
    stream_ids(answers.primitive_ids + row, left.primitive);
    stream_ids(answers.primitive_ids + row + 8, right.primitive);
    // Each half's uv fill a line, and the two halves' normals three (a line shared in the middle).
    for (const auto& [eight, first] : {std::pair{&left, row}, std::pair{&right, row + 8}}) {
        _mm256_stream_ps(answers.uvs + 2 * first, eight->uv[0]);
        _mm256_stream_ps(answers.uvs + 2 * first + 8, eight->uv[1]);
    }
    for (const auto& [eight, first] : {std::pair{&left, row}, std::pair{&right, row + 8}}) {
        for (int k = 0; k < 6; ++k)
            _mm_stream_ps(answers.normals + 3 * first + 4 * k, eight->normal[k]);
    }
}

#endif

// The answers of one group, a lane at a time.
void store_group(const HitPacket& hits, const PacketRows& where, int group, const CastAnswers& answers,
                 const HitTables& tables) {
    const auto g = static_cast<std::size_t>(group);
    for (int index = 0; index < where.count[g]; ++index) {
        const int lane = group * kGroupLanes + index;
        const std::size_t i = where.row[g] + static_cast<std::size_t>(index);
        const std::int32_t prim = hits.prim[lane];
        const bool hit = prim >= 0;
        answers.t_hit[i] = hits.t[lane];
        std::tie(answers.geometry_ids[i], answers.primitive_ids[i]) =
            hit ? tables.geometries.locate(prim) : std::pair{kInvalidId, kInvalidId};
        answers.uvs[2 * i] = hit ? hits.u[lane] : 0.0f;
        answers.uvs[2 * i + 1] = hit ? hits.v[lane] : 0.0f;
        std::copy_n(tables.normals.xyz + 3 * static_cast<std::ptrdiff_t>(prim), 3, answers.normals + 3 * i);
    }
}

}  // namespace

bool load_rays(const float* rows, const PacketRows& where, RayPacket& rays) {
    bool finite = true;
    for (std::size_t g = 0; g < where.row.size(); g += 2) {
        const int lane = static_cast<int>(g) * kGroupLanes;
#if defined(__AVX2__)
        if (where.count[g] == kGroupLanes && where.count[g + 1] == kGroupLanes) {
            finite &=
                load_eight(rows + kFields * where.row[g], rows + kFields * where.row[g + 1], rays, lane);
            continue;
        }
#endif
        for (int k = 0; k < 2 * kGroupLanes; ++k) {
            const std::size_t group = g + static_cast<std::size_t>(k / kGroupLanes);
            const int index = k % kGroupLanes;
            const float* const row =
                index < where.count[group]
                    ? rows + kFields * (where.row[group] + static_cast<std::size_t>(index))
                    : nullptr;
            set_lane(rays, lane + k, row);
            finite &= row == nullptr || finite_row(row);
        }
    }
    std::fill(std::begin(rays.tnear), std::end(rays.tnear), 0.0f);
    std::fill(std::begin(rays.tfar), std::end(rays.tfar), kInfinity);
    rays.size = RayPacket::kMaxSize;
    return finite;
}

std::size_t first_bad_row(const float* rows, const PacketRows& where) {
    std::size_t first = SIZE_MAX;
    for (std::size_t g = 0; g < where.row.size(); ++g) {
        for (int index = 0; index < where.count[g]; ++index) {
            const std::size_t row = where.row[g] + static_cast<std::size_t>(index);
            if (!finite_row(rows + kFields * row)) first = std::min(first, row);
        }
    }
    return first;
}

std::size_t load_ray_records(const float* rows, std::span<const PacketRows> packets, std::vector<Ray>& rays) {
    rays.resize(packets.size() * RayPacket::kMaxSize);
    std::size_t first_bad = packets.size();
    Ray* ray = rays.data();
    for (std::size_t packet = 0; packet < packets.size(); ++packet) {
        const PacketRows& where = packets[packet];
        bool finite = true;
        for (std::size_t g = 0; g < where.row.size(); ++g) {
            const float* row = rows + kFields * where.row[g];
            for (int index = 0; index < kGroupLanes; ++index, ++ray) {
#if defined(__AVX2__)
                // A record is one 8-float store: the row's six floats (a masked load reads nothing past
                // them), then tnear 0 and tfar inf.
                static_assert(sizeof(Ray) == 8 * sizeof(float));
                if (index < where.count[g]) {
                    const __m256 fields =
                        _mm256_maskload_ps(row, _mm256_setr_epi32(-1, -1, -1, -1, -1, -1, 0, 0));
                    finite &= _mm256_movemask_ps(finite_lanes(fields)) == 0xFF;
                    _mm256_storeu_ps(reinterpret_cast<float*>(ray),
                                     _mm256_or_ps(fields, _mm256_setr_ps(0, 0, 0, 0, 0, 0, 0, kInfinity)));
                    row += kFields;
                    continue;
                }
#endif
                if (index < where.count[g]) {
                    finite &= finite_row(row);
                    *ray = {{row[0], row[1], row[2]}, {row[3], row[4], row[5]}, 0.0f, kInfinity};
                    row += kFields;
                } else {
                    *ray = {{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 0.0f, kInfinity};
                }
            }
        }
        if (!finite && first_bad == packets.size()) first_bad = packet;
    }
    return first_bad;
}

void gather_hits(std::span<const Hit> hits, std::size_t packet, HitPacket& out) {
    const Hit* first = hits.data() + packet * RayPacket::kMaxSize;
    for (int lane = 0; lane < RayPacket::kMaxSize; lane += 4) {
#if defined(__SSE2__)
        // Four records are a 4x4 matrix of t, prim, u, v: one transpose gives the four fields' rows.
        const auto* record = reinterpret_cast<const float*>(first + lane);
        __m128 t = _mm_loadu_ps(record), prim = _mm_loadu_ps(record + 4), u = _mm_loadu_ps(record + 8),
               v = _mm_loadu_ps(record + 12);
        _MM_TRANSPOSE4_PS(t, prim, u, v);
        _mm_storeu_ps(out.t + lane, t);
        _mm_storeu_ps(reinterpret_cast<float*>(out.prim + lane), prim);
        _mm_storeu_ps(out.u + lane, u);
        _mm_storeu_ps(out.v + lane, v);
#else
        for (int k = 0; k < 4; ++k)
            out.set(lane + k, first[lane + k]);
#endif
    }
}

void prefetch_answers(const PacketRows& where, const CastAnswers& answers) {
    const auto prefetch_range = [](const void* first, std::size_t bytes) {
        const auto* const begin = static_cast<const char*>(first);
        for (std::size_t offset = 0; offset < bytes; offset += 64)
            __builtin_prefetch(begin + offset, 1);
        __builtin_prefetch(begin + bytes - 1, 1);
    };
    for (const auto& [low, high] : where.answer_pairs) {
        const std::size_t row = where.row[static_cast<std::size_t>(low)];
        const auto count = static_cast<std::size_t>(where.count[static_cast<std::size_t>(low)] +
                                                    where.count[static_cast<std::size_t>(high)]);
        if (count == 0) continue;
        prefetch_range(answers.t_hit + row, count * sizeof(float));
        prefetch_range(answers.geometry_ids + row, count * sizeof(std::uint32_t));
        prefetch_range(answers.primitive_ids + row, count * sizeof(std::uint32_t));
        prefetch_range(answers.uvs + 2 * row, 2 * count * sizeof(float));
        prefetch_range(answers.normals + 3 * row, 3 * count * sizeof(float));
    }
}

std::pair<std::uint32_t, std::uint32_t> GeometryStarts::locate(std::int32_t prim) const {
    std::uint32_t geometry = 0;
    return locate(prim, geometry);
}

std::pair<std::uint32_t, std::uint32_t> GeometryStarts::locate(std::int32_t prim,
                                                               std::uint32_t& geometry) const {
    const auto index = static_cast<std::uint32_t>(prim);
    // The geometry holding the index is the one non-empty range [first[g], first[g + 1]) around it.
    if (index < first[geometry] || index >= first[geometry + 1]) {
        const auto after = std::upper_bound(first.begin(), first.end() - 1, index);
        geometry = static_cast<std::uint32_t>(after - first.begin()) - 1;
    }
    return {geometry, index - first[geometry]};
}

void store_pairs(const HitPacket& hits, const PacketRows& where, const CastAnswers& answers,
                 const HitTables& tables) {
    for (const auto& [low, high] : where.answer_pairs) {
#if defined(__AVX2__)
        if (where.count[static_cast<std::size_t>(low)] == kGroupLanes &&
            where.count[static_cast<std::size_t>(high)] == kGroupLanes) {
            EightAnswers(hits, low * kGroupLanes, high * kGroupLanes, tables)
                .store(answers, where.row[static_cast<std::size_t>(low)]);
            continue;
        }
#endif
        store_group(hits, where, low, answers, tables);
        store_group(hits, where, high, answers, tables);
    }
}

void stream_tile_pair(const HitPacket& left_hits, const HitPacket& right_hits, const PacketRows& left,
                      [[maybe_unused]] const PacketRows& right, const CastAnswers& answers,
                      const HitTables& tables) {
#if defined(__AVX2__)
    // Pair k of either tile is the tile's row k (RayChunks::image_chunk): the left tile's eight answers, then
    // the right's, eight rays on (RayChunks::tile_pair), fill the row's lines.
    for (const auto& [low, high] : left.answer_pairs) {
        stream_sixteen(EightAnswers(left_hits, low * kGroupLanes, high * kGroupLanes, tables),
                       EightAnswers(right_hits, low * kGroupLanes, high * kGroupLanes, tables), answers,
                       left.row[static_cast<std::size_t>(low)]);
    }
#else
    store_pairs(left_hits, left, answers, tables);
    store_pairs(right_hits, right, answers, tables);
#endif
}

void finish_streamed_stores() {
#if defined(__AVX2__)
    _mm_sfence();
#endif
}

bool lines_aligned(const CastAnswers& answers) {
    const auto aligned = [](const void* array) { return reinterpret_cast<std::uintptr_t>(array) % 64 == 0; };
    return aligned(answers.t_hit) && aligned(answers.geometry_ids) && aligned(answers.primitive_ids) &&
           aligned(answers.uvs) && aligned(answers.normals);
}

RayChunks::RayChunks(std::span<const std::size_t> shape) {
    for (const std::size_t extent : shape)
        ray_count_ *= extent;
    const auto side = static_cast<std::size_t>(PinholeCamera::kTileSide);
    if (shape.size() >= 2 && shape[shape.size() - 2] >= side && shape.back() >= side) {
        height_ = shape[shape.size() - 2];
        width_ = shape.back();
        bands_ = (height_ + side - 1) / side;
        segments_ = (width_ + kChunkPackets * side - 1) / (kChunkPackets * side);
        chunk_count_ = ray_count_ / (height_ * width_) * bands_ * segments_;
    } else {
        const std::size_t chunk_rays = kChunkPackets * RayPacket::kMaxSize;
        chunk_count_ = (ray_count_ + chunk_rays - 1) / chunk_rays;
    }
}

void RayChunks::chunk(std::size_t index, std::vector<PacketRows>& packets) const {
    packets.clear();
    if (images()) {
        image_chunk(index, packets);
    } else {
        flat_chunk(index, packets);
    }
}

bool RayChunks::tile_pair(const PacketRows& left, const PacketRows& right) const {
    // Sixteen answers fill a line of every array: 64 bytes of t and of each id, 128 of uv, 192 of normals.
    constexpr std::size_t kLineRays = 2 * PinholeCamera::kTileSide;
    const auto full = [](const PacketRows& where) {
        return std::all_of(where.count.begin(), where.count.end(),
                           [](int count) { return count == kGroupLanes; });
    };
    // A tile's lane 0 is its top left ray: the right tile starts eight rays on, and the pair on a line.
    return images() && width_ % kLineRays == 0 && left.row[0] % kLineRays == 0 &&
           right.row[0] == left.row[0] + PinholeCamera::kTileSide && full(left) && full(right);
}

void RayChunks::image_chunk(std::size_t index, std::vector<PacketRows>& packets) const {
    static_assert(PinholeCamera::kBlockSide == kGroupLanes && PinholeCamera::kTileSide == 2 * kGroupLanes);
    // A group is a row of a block, four pixels from tile_column(4g) in row tile_row(4g); its answers pair
    // with those of the group on its right in the tile (column 4 on).
    static const auto tile_pairs = [] {
        std::array<std::array<int, 2>, kGroups / 2> pairs{};
        for (int group = 0; group < kGroups; ++group) {
            const int lane = group * kGroupLanes;
            pairs[static_cast<std::size_t>(PinholeCamera::tile_row(lane))]
                 [static_cast<std::size_t>(PinholeCamera::tile_column(lane) / kGroupLanes)] = group;
        }
        return pairs;
    }();
    const auto side = static_cast<std::size_t>(PinholeCamera::kTileSide);
    const std::size_t image = index / (bands_ * segments_), band = index / segments_ % bands_;
    const std::size_t first_x = index % segments_ * kChunkPackets * side;
    const std::size_t last_x = std::min(width_, first_x + kChunkPackets * side);
    const std::size_t first_y = band * side, last_y = std::min(height_, first_y + side);
    const std::size_t image_first = image * height_ * width_;
    for (std::size_t x0 = first_x; x0 < last_x; x0 += side) {
        PacketRows& where = packets.emplace_back();
        where.answer_pairs = tile_pairs;
        for (std::size_t g = 0; g < where.row.size(); ++g) {
            const int lane = static_cast<int>(g) * kGroupLanes;
            const std::size_t y = first_y + static_cast<std::size_t>(PinholeCamera::tile_row(lane));
            const std::size_t x = x0 + static_cast<std::size_t>(PinholeCamera::tile_column(lane));
            where.row[g] = image_first + y * width_ + x;
            where.count[g] = y < last_y && x < last_x
                                 ? static_cast<int>(std::min<std::size_t>(kGroupLanes, last_x - x))
                                 : 0;
        }
    }
}

void RayChunks::flat_chunk(std::size_t index, std::vector<PacketRows>& packets) const {
    const std::size_t chunk_rays = kChunkPackets * RayPacket::kMaxSize;
    const std::size_t first = index * chunk_rays, last = std::min(ray_count_, first + chunk_rays);
    for (std::size_t packet = first; packet < last; packet += RayPacket::kMaxSize) {
        PacketRows& where = packets.emplace_back();
        for (std::size_t g = 0; g < where.row.size(); ++g) {
            where.row[g] = packet + kGroupLanes * g;
            where.count[g] =
                static_cast<int>(std::min<std::size_t>(kGroupLanes, last - std::min(last, where.row[g])));
        }
        for (std::size_t pair = 0; pair < where.answer_pairs.size(); ++pair)
            where.answer_pairs[pair] = {2 * static_cast<int>(pair), 2 * static_cast<int>(pair) + 1};
    }
}

}  // namespace lancer::python
