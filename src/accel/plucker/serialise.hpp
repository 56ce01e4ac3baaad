// The Plücker octree on disk (Portalez & Duguet 2016, section 3: the cells, the triangles, the boxes and the
// cube map), with the geometry it was built on, so that `lancer convert` writes it once and `lancer render`
// and `lancer rays` load it back without a build. Versioned (magic, version, header size, layout flags),
// little-endian, read by memcpy.
//
// File: a 136-byte header (PluckerFileHeader), then the arrays in this order, each packed:
//   triangles  36 B each  the geometry, global order        spheres   20 B each
//   cells       4 B each  the word stream                   primitives 40 B each (PluckerPrimitive)
//   boxes      36 B each  (PluckerBox)                      texels     4 B each (cube map, faces 0..5)
//   locate      4 B each
// Reading never trusts the file: the header's counts must add up to the file's size before anything is
// allocated (so a few corrupted bytes cannot ask for gigabytes), a checksum covers the arrays, and the
// structure is rebuilt from its tree (recover_octree, layout_octree) and must come out identical, which
// bounds every address and proves every link (docs/accel/plucker.md, "File").
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "accel/plucker/layout.hpp"
#include "lancer/world.hpp"

namespace lancer::plucker {

inline constexpr char kFileMagic[8] = {'L', 'A', 'N', 'C', 'E', 'R', 'P', 'O'};
// Raised whenever a layout change makes older files' arrays mean something else (docs/accel/plucker.md,
// "File").
inline constexpr std::uint32_t kFileVersion = 4;

struct PluckerFileHeader {
    char magic[8];                           // 8
    std::uint32_t version;                   // 4
    std::uint32_t header_bytes;              // 4: sizeof(PluckerFileHeader)
    std::uint32_t flags;                     // 4: 1 stored boxes, 2 balanced, 4 Morton order
    std::uint32_t triangle_test;             // 4: 0 Moller-Trumbore, 1 watertight
    float cube_lo[3];                        // 12
    float cube_size;                         // 4
    float tolerance;                         // 4
    std::uint32_t cube_map_level[6];         // 24
    std::uint32_t reserved;                  // 4: zero
    std::uint64_t triangles, spheres;        // 16
    std::uint64_t cells, primitives, boxes;  // 24
    std::uint64_t texels, locate;            // 16
    std::uint64_t checksum;                  // 8: FNV-1a 64 of every byte after the header
};
static_assert(sizeof(PluckerFileHeader) == 136);

// The public error of a `.plo` file that cannot be read or written (lancer/world.hpp).
using PluckerFileError = StructureFileError;

struct PluckerFile {
    std::vector<Triangle> triangles;
    std::vector<Sphere> spheres;
    TriangleTest triangle_test = TriangleTest::MollerTrumbore;
    PluckerLayout layout;
};

// Throws PluckerFileError when the file cannot be written.
void write_plucker_file(const std::filesystem::path& file, const Geometry& geometry,
                        const PluckerLayout& layout, TriangleTest triangle_test);

// Throws PluckerFileError (see above).
[[nodiscard]] PluckerFile read_plucker_file(const std::filesystem::path& file);

}  // namespace lancer::plucker
