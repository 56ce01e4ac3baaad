#include "accel/plucker/serialise.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "accel/build_util.hpp"
#include "accel/plucker/build.hpp"
#include "core/ray_conditioning.hpp"

namespace lancer::plucker {
namespace {

static_assert(std::endian::native == std::endian::little,
              "Plücker octree files are little-endian and read by memcpy: add byte swapping for this target");
static_assert(sizeof(Sphere) == 20);

constexpr std::uint32_t kStoredBoxesFlag = 1, kBalancedFlag = 2, kMortonFlag = 4;

class Fnv1a {
  public:
    void add(std::span<const std::byte> bytes) {
        for (const std::byte b : bytes) {
            hash_ ^= static_cast<std::uint64_t>(b);
            hash_ *= 0x100000001b3ull;
        }
    }
    [[nodiscard]] std::uint64_t value() const { return hash_; }

  private:
    std::uint64_t hash_ = 0xcbf29ce484222325ull;
};

template <class T>
std::span<const std::byte> bytes_of(const std::vector<T>& v) {
    return std::as_bytes(std::span(v));
}

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what) {
    throw PluckerFileError(file.string() + ": " + what);
}

}  // namespace

void write_plucker_file(const std::filesystem::path& file, const Geometry& geometry,
                        const PluckerLayout& layout, TriangleTest triangle_test) {
    const std::vector<Triangle> triangles(geometry.triangles.begin(), geometry.triangles.end());
    const std::vector<Sphere> spheres(geometry.spheres.begin(), geometry.spheres.end());
    PluckerFileHeader header{};
    std::memcpy(header.magic, kFileMagic, sizeof(kFileMagic));
    header.version = kFileVersion;
    header.header_bytes = sizeof(PluckerFileHeader);
    header.flags = (layout.options.stored_boxes ? kStoredBoxesFlag : 0) |
                   (layout.options.balanced ? kBalancedFlag : 0) | (layout.options.morton ? kMortonFlag : 0);
    header.triangle_test = triangle_test == TriangleTest::Watertight ? 1 : 0;
    for (int axis = 0; axis < 3; ++axis)
        header.cube_lo[axis] = layout.cube.lo[axis];
    header.cube_size = layout.cube.size;
    header.tolerance = layout.tolerance;
    std::copy(layout.cube_map.level.begin(), layout.cube_map.level.end(), header.cube_map_level);
    header.triangles = triangles.size();
    header.spheres = spheres.size();
    header.cells = layout.cells.size();
    header.primitives = layout.primitives.size();
    header.boxes = layout.boxes.size();
    header.texels = layout.cube_map.texels.size();
    header.locate = layout.locate.size();
    const std::span<const std::byte> arrays[] = {bytes_of(triangles),    bytes_of(spheres),
                                                 bytes_of(layout.cells), bytes_of(layout.primitives),
                                                 bytes_of(layout.boxes), bytes_of(layout.cube_map.texels),
                                                 bytes_of(layout.locate)};
    Fnv1a checksum;
    for (const auto& array : arrays)
        checksum.add(array);
    header.checksum = checksum.value();

    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    if (!out) fail(file, "cannot open for writing");
    out.write(reinterpret_cast<const char*>(&header), sizeof(header));
    for (const auto& array : arrays)
        out.write(reinterpret_cast<const char*>(array.data()), static_cast<std::streamsize>(array.size()));
    out.close();
    if (!out) fail(file, "write error");
}

PluckerFile read_plucker_file(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary | std::ios::ate);
    if (!in) fail(file, "cannot open");
    const auto file_size = static_cast<std::uint64_t>(in.tellg());
    in.seekg(0);
    PluckerFileHeader header{};
    const auto available = static_cast<std::streamsize>(std::min<std::uint64_t>(file_size, sizeof(header)));
    if (!in.read(reinterpret_cast<char*>(&header), available)) fail(file, "read error");
    if (file_size < sizeof(kFileMagic) || std::memcmp(header.magic, kFileMagic, sizeof(kFileMagic)) != 0)
        fail(file, "not a lancer Plücker octree file (wrong magic; write one with `lancer convert`)");
    if (file_size < sizeof(header))
        fail(file, "truncated: shorter than the " + std::to_string(sizeof(header)) + "-byte header");
    if (header.version != kFileVersion)
        fail(file, "format version " + std::to_string(header.version) + ", this lancer reads version " +
                       std::to_string(kFileVersion));
    if (header.header_bytes != sizeof(header) || header.reserved != 0)
        fail(file, "header layout differs from version " + std::to_string(kFileVersion));
    if ((header.flags & ~(kStoredBoxesFlag | kBalancedFlag | kMortonFlag)) != 0 || header.triangle_test > 1)
        fail(file, "unknown layout flags or triangle test");
    for (const std::uint32_t level : header.cube_map_level) {
        if (level > kMaxCubeMapLevel) fail(file, "cube map level " + std::to_string(level) + " out of range");
    }
    std::uint64_t expected_texels = 0;
    for (const std::uint32_t level : header.cube_map_level)
        expected_texels += std::uint64_t{1} << (2 * level);
    if (header.texels != expected_texels) fail(file, "cube map size does not match its levels");

    // Every count against what the file can hold, before anything is allocated.
    const std::pair<std::uint64_t, std::uint64_t> arrays[] = {{header.triangles, sizeof(Triangle)},
                                                              {header.spheres, sizeof(Sphere)},
                                                              {header.cells, 4},
                                                              {header.primitives, sizeof(PluckerPrimitive)},
                                                              {header.boxes, sizeof(PluckerBox)},
                                                              {header.texels, 4},
                                                              {header.locate, 4}};
    std::uint64_t payload = 0;
    for (const auto& [count, element] : arrays) {
        if (count > (file_size - sizeof(header)) / element)
            fail(file, "truncated: an array runs past the end");
        payload += count * element;
    }
    if (sizeof(header) + payload != file_size)
        fail(file, "truncated or padded: the header describes " + std::to_string(sizeof(header) + payload) +
                       " bytes, the file has " + std::to_string(file_size));
    if (header.triangles + header.spheres >
        static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max()))
        fail(file, "more primitives than a hit's 32-bit index can number");

    PluckerFile result;
    PluckerLayout& layout = result.layout;
    auto read = [&](auto& vector, std::uint64_t count) {
        vector.resize(static_cast<std::size_t>(count));
        if (!in.read(reinterpret_cast<char*>(vector.data()),
                     static_cast<std::streamsize>(
                         count * sizeof(typename std::decay_t<decltype(vector)>::value_type))))
            fail(file, "read error");
    };
    read(result.triangles, header.triangles);
    read(result.spheres, header.spheres);
    read(layout.cells, header.cells);
    read(layout.primitives, header.primitives);
    read(layout.boxes, header.boxes);
    read(layout.cube_map.texels, header.texels);
    read(layout.locate, header.locate);
    Fnv1a checksum;
    for (const auto& array : {bytes_of(result.triangles), bytes_of(result.spheres), bytes_of(layout.cells),
                              bytes_of(layout.primitives), bytes_of(layout.boxes),
                              bytes_of(layout.cube_map.texels), bytes_of(layout.locate)})
        checksum.add(array);
    if (checksum.value() != header.checksum) fail(file, "checksum mismatch: the file is corrupted");

    result.triangle_test =
        header.triangle_test == 1 ? TriangleTest::Watertight : TriangleTest::MollerTrumbore;
    layout.options = {(header.flags & kStoredBoxesFlag) != 0, (header.flags & kBalancedFlag) != 0,
                      (header.flags & kMortonFlag) != 0};
    layout.cube = {{header.cube_lo[0], header.cube_lo[1], header.cube_lo[2]}, header.cube_size};
    layout.tolerance = header.tolerance;
    layout.triangle_count = static_cast<std::uint32_t>(header.triangles);
    std::copy(std::begin(header.cube_map_level), std::end(header.cube_map_level),
              layout.cube_map.level.begin());
    std::uint32_t offset = 0;
    for (int face = 0; face < 6; ++face) {
        layout.cube_map.offset[static_cast<std::size_t>(face)] = offset;
        offset += 1u << (2 * layout.cube_map.level[static_cast<std::size_t>(face)]);
    }

    // The root cube and tolerance are the build's for this geometry, and the structure is the layout of its
    // own tree: rebuilt from `locate`, it must come out word for word the same. The tree was built on the
    // geometry at the scale the structures see it (Accel::built_geometry): a scene whose size lies outside
    // the ordinary range is checked scaled, as PluckerAccel::adopt will trace it.
    Geometry geometry{result.triangles, result.spheres};
    std::vector<Triangle> scaled_triangles;
    std::vector<Sphere> scaled_spheres;
    if (const int exponent = scene_scale_exponent(hit_bounds(geometry)); exponent != 0) {
        scale_geometry(geometry, exponent, scaled_triangles, scaled_spheres);
        geometry = {scaled_triangles, scaled_spheres};
    }
    const OctreeCube cube = octree_root_cube(geometry.bounds());
    if (!(cube.lo == layout.cube.lo && cube.size == layout.cube.size) ||
        layout.tolerance != geometric_tolerance(geometry.bounds()))
        fail(file, "the root cube does not match the geometry");
    const std::uint64_t primitive_count = header.triangles + header.spheres;
    for (const PluckerPrimitive& primitive : layout.primitives) {
        if (primitive.prim >= primitive_count) fail(file, "a triangle reference is out of range");
    }
    try {
        const Octree octree = recover_octree(layout);
        const PluckerLayout rebuilt = layout_octree(geometry, octree, layout.options);
        const bool same = rebuilt.cells == layout.cells && rebuilt.boxes.size() == layout.boxes.size() &&
                          std::equal(bytes_of(rebuilt.boxes).begin(), bytes_of(rebuilt.boxes).end(),
                                     bytes_of(layout.boxes).begin()) &&
                          rebuilt.primitives.size() == layout.primitives.size() &&
                          std::equal(bytes_of(rebuilt.primitives).begin(), bytes_of(rebuilt.primitives).end(),
                                     bytes_of(layout.primitives).begin()) &&
                          rebuilt.cube_map.level == layout.cube_map.level &&
                          rebuilt.cube_map.texels == layout.cube_map.texels &&
                          rebuilt.locate == layout.locate;
        if (!same)
            fail(file, "inconsistent structure: its links, boxes or cube map are not those of its own tree");
        layout.bounds = rebuilt.bounds;
    } catch (const std::invalid_argument& error) {
        fail(file, error.what());
    } catch (const std::length_error& error) {
        fail(file, error.what());
    }
    return result;
}

}  // namespace lancer::plucker
