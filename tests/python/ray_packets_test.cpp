// The Python module's way between NumPy's rows and packets (python/ray_packets.hpp), which needs no Python:
// over arrays of many shapes, every ray goes into exactly one lane, in tile_rays's order for images, and its
// answers come back to its own row. A stand-in for the trace answers each lane with values made from its ray.
#include "ray_packets.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "lancer/camera.hpp"

namespace lancer::python {
namespace {

// Ray `row`: an origin naming the row (exact in float for these sizes) and a direction that is never zero.
void fill_rows(std::vector<float>& rows) {
    for (std::size_t row = 0; row < rows.size() / 6; ++row) {
        const auto r = static_cast<float>(row);
        const float ray[6] = {r, 0.5f * r, -r, 1.0f, 2.0f + r, -3.0f};
        std::copy(ray, ray + 6, rows.begin() + static_cast<std::ptrdiff_t>(6 * row));
    }
}

// What the stand-in trace answers for the ray of `row`: every third a miss.
bool hits(std::size_t row) {
    return row % 3 != 0;
}

// An answer array of `count` values, each `fill` at first, starting on a 64-byte boundary (as cast_rays
// makes them) or 4 bytes after one, which answer_chunk must answer without streaming.
template <class T>
class AnswerArray {
  public:
    AnswerArray(std::size_t count, T fill, bool line_aligned) : storage_(count + 32, fill) {
        const auto address = reinterpret_cast<std::uintptr_t>(storage_.data());
        const std::size_t first = (64 - address % 64) % 64 / sizeof(T) + (line_aligned ? 0 : 1);
        values_ = std::span<T>(storage_).subspan(first, count);
    }
    AnswerArray(const AnswerArray&) = delete;
    AnswerArray(AnswerArray&&) noexcept = default;  // the moved vector keeps its buffer, so values_ too
    T* data() { return values_.data(); }
    const T& operator[](std::size_t i) const { return values_[i]; }
    [[nodiscard]] std::size_t size() const { return values_.size(); }

  private:
    std::vector<T> storage_;
    std::span<T> values_;
};

struct Answers {
    Answers(std::size_t count, bool line_aligned)
        : t(count, -1.0f, line_aligned),
          geometry(count, 7, line_aligned),
          primitive(count, 7, line_aligned),
          uv(2 * count, -1.0f, line_aligned),
          normal(3 * count, -1.0f, line_aligned) {}
    CastAnswers view() { return {t.data(), geometry.data(), primitive.data(), uv.data(), normal.data()}; }
    AnswerArray<float> t;
    AnswerArray<std::uint32_t> geometry, primitive;
    AnswerArray<float> uv, normal;
};

// The stand-in's normal table, laid out as NormalTable says: triangle p's normal is (p, 1, 2).
std::vector<float> normal_table(std::size_t count) {
    std::vector<float> xyz(3, 0.0f);
    for (std::size_t p = 0; p < count; ++p)
        xyz.insert(xyz.end(), {static_cast<float>(p), 1.0f, 2.0f});
    xyz.push_back(0.0f);
    return xyz;
}

// Where the geometries of the stand-in's scene start: one geometry, or geometries of 1 to 13 triangles,
// most smaller than a pair of lanes, so that a pair's hits fall in several.
std::vector<std::uint32_t> geometry_starts(std::size_t count, bool several_geometries) {
    std::vector<std::uint32_t> first{0};
    for (std::uint32_t size = 1; several_geometries && first.back() + size < count; size = size % 13 + 1)
        first.push_back(first.back() + size);
    first.push_back(static_cast<std::uint32_t>(count));
    return first;
}

// Triangle p's ids, found by walking the starts (GeometryStarts::locate searches them).
std::pair<std::uint32_t, std::uint32_t> walked_ids(const std::vector<std::uint32_t>& first, std::size_t p) {
    std::uint32_t geometry = 0;
    while (first[geometry + 1] <= p)
        ++geometry;
    return {geometry, static_cast<std::uint32_t>(p) - first[geometry]};
}

// Traces every chunk of an array of leading shape `shape` through the stand-in and answer_chunk; checks each
// packet's lanes.
Answers cast(const std::vector<std::size_t>& shape, bool several_geometries, bool line_aligned) {
    std::size_t count = 1;
    for (const std::size_t extent : shape)
        count *= extent;
    std::vector<float> rows(6 * count);
    fill_rows(rows);
    const std::vector<float> normals = normal_table(count);
    const std::vector<std::uint32_t> starts = geometry_starts(count, several_geometries);
    const HitTables tables{NormalTable{normals.data() + 3}, GeometryStarts{starts}};
    Answers answers(count, line_aligned);
    std::vector<int> lanes_of_row(count, 0);
    const RayChunks chunks(shape);
    const auto trace = [&](const PacketRows& where, HitPacket& hit_packet) {
        RayPacket rays;
        EXPECT_TRUE(load_rays(rows.data(), where, rays));
        EXPECT_EQ(rays.size, RayPacket::kMaxSize);
        for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
            EXPECT_EQ(rays.tnear[lane], 0.0f);
            EXPECT_EQ(rays.tfar[lane], kInfinity);
            const Ray ray = rays.ray(lane);
            if (ray.direction == Vec3f(0.0f)) {  // a padding lane: misses
                hit_packet.set(lane, Hit{});
                continue;
            }
            const auto row = static_cast<std::size_t>(ray.origin.x);
            EXPECT_EQ(ray.origin, Vec3f(ray.origin.x, 0.5f * ray.origin.x, -ray.origin.x));
            EXPECT_EQ(ray.direction, Vec3f(1.0f, 2.0f + ray.origin.x, -3.0f));
            ++lanes_of_row.at(row);
            const auto prim = static_cast<std::int32_t>(row);
            hit_packet.set(lane, hits(row) ? Hit{ray.origin.x + 0.5f, prim, 0.25f, 0.75f} : Hit{});
        }
        if (chunks.images()) {
            // Camera tiles: lane L at column tile_column(L) and row tile_row(L) of its tile.
            const std::size_t width = shape.back(), first = where.row[0];
            for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
                const std::size_t group = static_cast<std::size_t>(lane / kGroupLanes);
                if (lane % kGroupLanes >= where.count[group]) continue;
                EXPECT_EQ(where.row[group] + static_cast<std::size_t>(lane % kGroupLanes),
                          first + width * static_cast<std::size_t>(PinholeCamera::tile_row(lane)) +
                              static_cast<std::size_t>(PinholeCamera::tile_column(lane)));
            }
        }
    };
    std::vector<PacketRows> packets;
    for (std::size_t index = 0; index < chunks.size(); ++index) {
        chunks.chunk(index, packets);
        answer_chunk(chunks, packets, answers.view(), tables, trace);
    }
    for (std::size_t row = 0; row < count; ++row)
        EXPECT_EQ(lanes_of_row[row], 1) << "row " << row;
    return answers;
}

// The answers of `row`: the stand-in's for a hit, with ids `geometry` and `primitive`, Open3D's for a miss.
void check_answers(const Answers& answers, std::size_t row, std::uint32_t geometry, std::uint32_t primitive) {
    const auto r = static_cast<float>(row);
    if (hits(row)) {
        EXPECT_EQ(answers.t[row], r + 0.5f) << row;
        EXPECT_EQ(answers.geometry[row], geometry) << row;
        EXPECT_EQ(answers.primitive[row], primitive) << row;
        EXPECT_EQ(answers.uv[2 * row], 0.25f) << row;
        EXPECT_EQ(answers.uv[2 * row + 1], 0.75f) << row;
        EXPECT_EQ(answers.normal[3 * row], r) << row;
        EXPECT_EQ(answers.normal[3 * row + 1], 1.0f) << row;
        EXPECT_EQ(answers.normal[3 * row + 2], 2.0f) << row;
    } else {
        EXPECT_EQ(answers.t[row], kInfinity) << row;
        EXPECT_EQ(answers.geometry[row], kInvalidId) << row;
        EXPECT_EQ(answers.primitive[row], kInvalidId) << row;
        for (int k = 0; k < 2; ++k)
            EXPECT_EQ(answers.uv[2 * row + static_cast<std::size_t>(k)], 0.0f) << row;
        for (int k = 0; k < 3; ++k)
            EXPECT_EQ(answers.normal[3 * row + static_cast<std::size_t>(k)], 0.0f) << row;
    }
}

class RayPacketsShapes : public testing::TestWithParam<std::vector<std::size_t>> {};

// A hit's ids are those of its geometry. Arrays on 64-byte boundaries have tile pairs streamed where the
// shape has them, others not.
TEST_P(RayPacketsShapes, EveryRayIsTracedOnceAndAnsweredAtItsRow) {
    for (const bool line_aligned : {true, false}) {
        for (const bool several_geometries : {false, true}) {
            SCOPED_TRACE(std::string(line_aligned ? "arrays on lines" : "arrays off lines") + ", " +
                         (several_geometries ? "several geometries" : "one geometry"));
            const Answers answers = cast(GetParam(), several_geometries, line_aligned);
            const std::vector<std::uint32_t> starts = geometry_starts(answers.t.size(), several_geometries);
            for (std::size_t row = 0; row < answers.t.size(); ++row) {
                const auto [geometry, primitive] = walked_ids(starts, row);
                check_answers(answers, row, geometry, primitive);
            }
        }
    }
}

// Flat arrays around the group, packet and chunk sizes; images (both last axes 8 or more) around the tile
// and chunk widths, stacked; arrays too thin to be images; images whose width is a multiple of a streamed
// tile pair's (16), with bands whole and cut.
INSTANTIATE_TEST_SUITE_P(
    Shapes, RayPacketsShapes,
    testing::Values(std::vector<std::size_t>{}, std::vector<std::size_t>{0}, std::vector<std::size_t>{1},
                    std::vector<std::size_t>{5}, std::vector<std::size_t>{63}, std::vector<std::size_t>{64},
                    std::vector<std::size_t>{65}, std::vector<std::size_t>{2048},
                    std::vector<std::size_t>{2051}, std::vector<std::size_t>{8, 8},
                    std::vector<std::size_t>{9, 8}, std::vector<std::size_t>{8, 9},
                    std::vector<std::size_t>{13, 21}, std::vector<std::size_t>{3, 17, 300},
                    std::vector<std::size_t>{2, 16, 256}, std::vector<std::size_t>{7, 300},
                    std::vector<std::size_t>{300, 7}, std::vector<std::size_t>{4, 0, 9},
                    std::vector<std::size_t>{24, 48}, std::vector<std::size_t>{12, 48},
                    std::vector<std::size_t>{2, 8, 16}));

// Every index's ids, whatever geometry the search is told to try first, with empty geometries among the
// others (their start repeats the next one's).
TEST(RayPackets, GeometryStartsLocateEveryIndexFromAnyHint) {
    const std::vector<std::uint32_t> first{0, 3, 3, 5, 9, 9, 12};
    const GeometryStarts geometries{first};
    for (std::uint32_t p = 0; p < first.back(); ++p) {
        const auto expected = walked_ids(first, p);
        EXPECT_EQ(geometries.locate(static_cast<std::int32_t>(p)), expected) << p;
        for (std::uint32_t hint = 0; hint < geometries.geometry_count(); ++hint) {
            std::uint32_t geometry = hint;
            EXPECT_EQ(geometries.locate(static_cast<std::int32_t>(p), geometry), expected)
                << p << ", " << hint;
            EXPECT_EQ(geometry, expected.first) << p << ", " << hint;
        }
    }
}

TEST(RayPackets, AnyNonFiniteValueIsFoundWithItsRow) {
    for (const std::vector<std::size_t>& shape :
         {std::vector<std::size_t>{200}, std::vector<std::size_t>{19, 13}}) {
        const std::size_t count = shape.size() == 1 ? shape[0] : shape[0] * shape[1];
        for (const std::size_t bad_row : {std::size_t{0}, std::size_t{37}, count - 1}) {
            for (int field = 0; field < 6; ++field) {
                for (const float bad : {std::numeric_limits<float>::quiet_NaN(), kInfinity, -kInfinity}) {
                    std::vector<float> rows(6 * count);
                    fill_rows(rows);
                    rows[6 * bad_row + static_cast<std::size_t>(field)] = bad;
                    const RayChunks chunks(shape);
                    std::vector<PacketRows> packets;
                    int refused = 0;
                    for (std::size_t index = 0; index < chunks.size(); ++index) {
                        chunks.chunk(index, packets);
                        for (const PacketRows& where : packets) {
                            RayPacket rays;
                            if (load_rays(rows.data(), where, rays)) continue;
                            ++refused;
                            EXPECT_EQ(first_bad_row(rows.data(), where), bad_row);
                        }
                    }
                    EXPECT_EQ(refused, 1) << "row " << bad_row << ", field " << field;
                }
            }
        }
    }
}

// cast_rays's batch records are the packets' rays lane for lane (load_rays's), the first packet with a NaN
// or an infinity is named, and gather_hits gives back each packet's lanes of the batch's hits.
TEST(RayPackets, BatchRecordsAreThePacketsRaysAndHitsComeBackByLane) {
    for (const std::vector<std::size_t>& shape :
         {std::vector<std::size_t>{5000}, std::vector<std::size_t>{37, 45}}) {
        std::size_t count = 1;
        for (const std::size_t extent : shape)
            count *= extent;
        std::vector<float> rows(6 * count);
        fill_rows(rows);
        const RayChunks chunks(shape);
        std::vector<PacketRows> packets;
        std::vector<Ray> records;
        for (std::size_t index = 0; index < chunks.size(); ++index) {
            chunks.chunk(index, packets);
            ASSERT_EQ(load_ray_records(rows.data(), packets, records), packets.size());
            ASSERT_EQ(records.size(), packets.size() * RayPacket::kMaxSize);
            std::vector<Hit> hits(records.size());
            for (std::size_t k = 0; k < hits.size(); ++k)
                hits[k] = {static_cast<float>(k), static_cast<std::int32_t>(k), 0.5f * static_cast<float>(k),
                           -1.0f};
            for (std::size_t p = 0; p < packets.size(); ++p) {
                RayPacket rays;
                ASSERT_TRUE(load_rays(rows.data(), packets[p], rays));
                HitPacket gathered;
                gather_hits(hits, p, gathered);
                for (int lane = 0; lane < RayPacket::kMaxSize; ++lane) {
                    const Ray& record = records[p * RayPacket::kMaxSize + static_cast<std::size_t>(lane)];
                    const Ray expected = rays.ray(lane);
                    EXPECT_EQ(record.origin, expected.origin);
                    EXPECT_EQ(record.direction, expected.direction);
                    EXPECT_EQ(record.tnear, 0.0f);
                    EXPECT_EQ(record.tfar, kInfinity);
                    const Hit& hit = hits[p * RayPacket::kMaxSize + static_cast<std::size_t>(lane)];
                    EXPECT_EQ(gathered.t[lane], hit.t);
                    EXPECT_EQ(gathered.prim[lane], hit.prim);
                    EXPECT_EQ(gathered.u[lane], hit.u);
                    EXPECT_EQ(gathered.v[lane], hit.v);
                }
            }
        }
        rows[6 * (count - 1) + 4] = std::numeric_limits<float>::quiet_NaN();
        chunks.chunk(chunks.size() - 1, packets);
        const std::size_t bad = load_ray_records(rows.data(), packets, records);
        ASSERT_LT(bad, packets.size());
        EXPECT_EQ(first_bad_row(rows.data(), packets[bad]), count - 1);
    }
}

}  // namespace
}  // namespace lancer::python
