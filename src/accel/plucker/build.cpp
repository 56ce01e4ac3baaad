#include "accel/plucker/build.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

#include "accel/plucker/balance.hpp"
#include "accel/plucker/conventions.hpp"
#include "core/parallel.hpp"

namespace lancer::plucker {
namespace {

// Leaves (and, in the unconstrained variant, inner cells other than the root) in stream order.
std::vector<std::uint32_t> record_order(const Octree& octree, const PluckerLayoutOptions& options) {
    std::vector<std::uint32_t> leaves, inner;
    auto add = [&](std::uint32_t index) {
        if (octree.cells[index].is_leaf())
            leaves.push_back(index);
        else if (index != 0 && !options.balanced)
            inner.push_back(index);
    };
    if (options.morton) {
        // Depth first with children in Morton order (x_bit | y_bit << 1 | z_bit << 2).
        std::vector<std::uint32_t> stack = {0};
        while (!stack.empty()) {
            const std::uint32_t index = stack.back();
            stack.pop_back();
            add(index);
            const OctreeCell& cell = octree.cells[index];
            if (cell.is_leaf()) continue;
            for (std::uint32_t child = 8; child-- > 0;)
                stack.push_back(cell.first_child + child);
        }
    } else {
        for (std::uint32_t index = 0; index < octree.cells.size(); ++index)
            add(index);
    }
    leaves.insert(leaves.end(), inner.begin(), inner.end());
    return leaves;
}

// body(record) for every record: in parallel with oneTBB (each call writes only its record's places).
template <class Body>
void for_each_record(std::size_t records, Body&& body) {
    parallel::for_each_index(0, records, body);
}

PluckerBox box_of(const OctreeCube& cube, float tolerance, const OctreeCell& cell) {
    PluckerBox box{};
    for (int axis = 0; axis < 3; ++axis) {
        const std::uint32_t c = cell.coordinate(axis);
        box.planes[static_cast<std::size_t>(axis)] = exit_plane_of(cube, tolerance, axis, cell.level, c);
        box.planes[static_cast<std::size_t>(3 + axis)] = cube.plane(axis, cell.level + 1, 2u * c + 1u);
        box.planes[static_cast<std::size_t>(6 + axis)] =
            exit_plane_of(cube, tolerance, axis, cell.level, c + 1u);
    }
    return box;
}

// The layer of cells of each level that holds a face of the bounds: the cells containing its plane, ties
// to the side of the rays that enter through it (walk.hpp's entry_leaf locates them the same way).
using FaceLayers = std::array<std::array<std::uint32_t, kOctreeMaxLevel + 1>, 6>;

FaceLayers face_layers(const PluckerLayout& layout) {
    FaceLayers layers{};
    for (int face = 0; face < 6; ++face) {
        const int axis = face_axis(face);
        const bool upper = face_side(face) != 0;
        const float plane = upper ? layout.bounds.hi[axis] : layout.bounds.lo[axis];
        for (std::uint32_t level = 0; level <= static_cast<std::uint32_t>(kOctreeMaxLevel); ++level)
            layers[static_cast<std::size_t>(face)][level] =
                cell_index(layout.cube, axis, level, plane, upper ? 0u : 1u);
    }
    return layers;
}

void fill_cube_map(const Octree& octree, const std::vector<std::uint32_t>& address, PluckerLayout& layout) {
    const FaceLayers layers = face_layers(layout);
    auto in_layer = [&](const OctreeCell& cell, int face) {
        return cell.coordinate(face_axis(face)) ==
               layers[static_cast<std::size_t>(face)][static_cast<std::size_t>(cell.level)];
    };
    CubeMap& map = layout.cube_map;
    map.level.fill(0);
    for (const OctreeCell& cell : octree.cells) {
        if (!cell.is_leaf()) continue;
        for (int face = 0; face < 6; ++face) {
            if (!in_layer(cell, face)) continue;
            auto& level = map.level[static_cast<std::size_t>(face)];
            level = std::max<std::uint32_t>(level, std::min<std::uint32_t>(cell.level, kMaxCubeMapLevel));
        }
    }
    std::size_t texels = 0;
    for (int face = 0; face < 6; ++face) {
        map.offset[static_cast<std::size_t>(face)] = static_cast<std::uint32_t>(texels);
        texels += std::size_t{1} << (2 * map.level[static_cast<std::size_t>(face)]);
    }
    map.texels.assign(texels, 0);
    // Every texel of a face is the cell of that face's level and layer that contains it: a leaf of that level
    // or coarser (its address), or an inner cell of that level (its tree index, tagged).
    for (std::uint32_t index = 0; index < octree.cells.size(); ++index) {
        const OctreeCell& cell = octree.cells[index];
        for (int face = 0; face < 6; ++face) {
            const std::uint32_t level = map.level[static_cast<std::size_t>(face)];
            const int axis = face_axis(face);
            if (!in_layer(cell, face)) continue;
            const bool covers = cell.is_leaf() ? cell.level <= level : cell.level == level;
            if (!covers) continue;
            const std::uint32_t value = cell.is_leaf() ? address[index] : (index | kInnerBit);
            const int shift = static_cast<int>(level) - cell.level;
            const std::uint32_t u = cell.coordinate(lower_in_face_axis(axis)) << shift;
            const std::uint32_t v = cell.coordinate(upper_in_face_axis(axis)) << shift;
            const std::uint32_t span = 1u << shift;
            for (std::uint32_t j = v; j < v + span; ++j) {
                for (std::uint32_t i = u; i < u + span; ++i)
                    map.texels[map.offset[static_cast<std::size_t>(face)] + i + (j << level)] = value;
            }
        }
    }
}

}  // namespace

PluckerLayout layout_octree(const Geometry& geometry, const Octree& octree,
                            const PluckerLayoutOptions& options) {
    PluckerLayout layout;
    layout.options = options;
    layout.cube = octree.cube;
    layout.tolerance = octree.tolerance;
    // An empty geometry has no bounds: its walk stays in the root.
    const Box3f bounds = geometry.bounds();
    layout.bounds = bounds.empty() ? Box3f{octree.cube.lo, octree.cube.lo + Vec3f(octree.cube.size)}
                                   : bounds.grown(octree.tolerance);
    layout.triangle_count = static_cast<std::uint32_t>(geometry.triangles.size());

    const std::vector<std::uint32_t> order = record_order(octree, options);
    const std::uint32_t header = header_words(options.stored_boxes);
    const std::uint32_t geometry_words = box_words(options.stored_boxes);

    // Neighbour lists and record sizes (each record's own: in parallel with TBB), then addresses.
    std::vector<std::array<FaceNeighbours, 6>> neighbours(order.size());
    std::vector<std::uint32_t> record_words(order.size());
    auto find_neighbours = [&](std::size_t record) {
        const std::uint32_t index = order[record];
        if (!octree.cells[index].is_leaf()) {
            record_words[record] = geometry_words + 8;
            return;
        }
        std::size_t total = 0;
        for (int face = 0; face < 6; ++face) {
            auto& list = neighbours[record][static_cast<std::size_t>(face)];
            list = face_neighbours(octree, index, face, !options.balanced);
            if (options.balanced) {
                for (const std::uint32_t neighbour : list) {
                    if (!octree.cells[neighbour].is_leaf())
                        throw std::invalid_argument("plucker layout: the octree is not 2:1 balanced");
                }
            }
            total += list.size();
        }
        record_words[record] = header + static_cast<std::uint32_t>(total);
    };
    for_each_record(order.size(), find_neighbours);
    // Each record's first word and, for a leaf, its first primitive copy, in record order: the records are
    // then written in parallel, each at its own place, so that the layout does not depend on the threads.
    std::vector<std::uint32_t> address(octree.cells.size(), 0);
    std::vector<std::size_t> first_primitive(order.size(), 0);
    std::size_t words = 0, primitives = 0;
    for (std::size_t record = 0; record < order.size(); ++record) {
        address[order[record]] = static_cast<std::uint32_t>(std::min<std::size_t>(words, kAddressMask));
        words += record_words[record];
        first_primitive[record] = primitives;
        const OctreeCell& cell = octree.cells[order[record]];
        if (cell.is_leaf()) primitives += cell.ref_count();
    }
    if (words > kAddressMask) throw std::length_error("plucker layout: more than 2^31 words of cells");
    if (primitives > std::numeric_limits<std::uint32_t>::max())
        throw std::length_error("plucker layout: more than 2^32 triangle references");

    auto link = [&](std::uint32_t index) {
        return octree.cells[index].is_leaf() ? address[index] : (address[index] | kInnerBit);
    };
    layout.cells.resize(words);
    layout.primitives.resize(primitives);
    if (options.stored_boxes) layout.boxes.resize(order.size());
    auto write_record = [&](std::size_t record) {
        const std::uint32_t index = order[record];
        const OctreeCell& cell = octree.cells[index];
        std::uint32_t* out = layout.cells.data() + address[index];
        const std::uint32_t box_or_position[2] = {
            options.stored_boxes
                ? static_cast<std::uint32_t>(record)
                : static_cast<std::uint32_t>(cell.x) | static_cast<std::uint32_t>(cell.y) << 16,
            static_cast<std::uint32_t>(cell.z) | static_cast<std::uint32_t>(cell.level) << 16};
        if (options.stored_boxes) layout.boxes[record] = box_of(octree.cube, octree.tolerance, cell);
        if (!cell.is_leaf()) {
            out = std::copy(box_or_position, box_or_position + geometry_words, out);
            for (std::uint32_t child = 0; child < 8; ++child)
                *out++ = link(cell.first_child + child);
            return;
        }
        *out++ = cell.ref_count();
        *out++ = static_cast<std::uint32_t>(first_primitive[record]);
        out = std::copy(box_or_position, box_or_position + geometry_words, out);
        std::uint32_t ends = 0, end = 0;
        for (int face = 0; face < 6; ++face) {
            end += static_cast<std::uint32_t>(neighbours[record][static_cast<std::size_t>(face)].size());
            ends |= end << (5 * face);
        }
        *out++ = ends;
        for (const auto& list : neighbours[record]) {
            for (const std::uint32_t neighbour : list)
                *out++ = link(neighbour);
        }
        PluckerPrimitive* primitive = layout.primitives.data() + first_primitive[record];
        for (std::uint32_t r = cell.ref_begin; r < cell.ref_end; ++r, ++primitive) {
            const std::uint32_t prim = octree.references[r];
            if (prim < layout.triangle_count) primitive->triangle = geometry.triangles[prim];
            primitive->prim = prim;
        }
    };
    for_each_record(order.size(), write_record);

    fill_cube_map(octree, address, layout);
    layout.locate.resize(octree.cells.size());
    for (std::uint32_t index = 0; index < octree.cells.size(); ++index) {
        const OctreeCell& cell = octree.cells[index];
        layout.locate[index] = cell.is_leaf() ? address[index] << 1 : (cell.first_child << 1 | 1u);
    }
    return layout;
}

Octree recover_octree(const PluckerLayout& layout) {
    auto fail = [](const std::string& what) { throw std::invalid_argument("plucker structure: " + what); };
    Octree octree;
    octree.cube = layout.cube;
    octree.tolerance = layout.tolerance;
    const std::size_t count = layout.locate.size();
    if (count == 0) fail("no cells");
    if (count > std::size_t{kAddressMask}) fail("too many cells");
    octree.cells.resize(count);
    std::vector<bool> has_parent(count, false);
    const std::uint32_t header = header_words(layout.options.stored_boxes);
    for (std::size_t index = 0; index < count; ++index) {
        if (index > 0 && !has_parent[index]) fail("cell " + std::to_string(index) + " has no parent");
        OctreeCell& cell = octree.cells[index];
        const std::uint32_t word = layout.locate[index];
        if (word & 1u) {
            const std::uint32_t first_child = word >> 1;
            if (first_child <= index || std::size_t{first_child} + 8 > count)
                fail("cell " + std::to_string(index) + ": children out of range");
            if (cell.level >= kOctreeMaxLevel) fail("cell " + std::to_string(index) + " is too deep");
            cell.first_child = first_child;
            for (std::uint32_t child = 0; child < 8; ++child) {
                if (has_parent[first_child + child]) fail("a cell has two parents");
                has_parent[first_child + child] = true;
                OctreeCell& c = octree.cells[first_child + child];
                c.level = static_cast<std::uint8_t>(cell.level + 1);
                c.x = static_cast<std::uint16_t>(2u * cell.x + (child & 1u));
                c.y = static_cast<std::uint16_t>(2u * cell.y + ((child >> 1) & 1u));
                c.z = static_cast<std::uint16_t>(2u * cell.z + ((child >> 2) & 1u));
            }
            continue;
        }
        const std::uint32_t address = word >> 1;
        if (layout.cells.size() < header || address > layout.cells.size() - header)
            fail("leaf " + std::to_string(index) + ": address out of range");
        const std::uint64_t t_count = layout.cells[address + kTriangleCount];
        const std::uint64_t t_offset = layout.cells[address + kTriangleOffset];
        // Leaves own disjoint ranges, so the references never outnumber the stored triangles.
        if (t_offset + t_count > layout.primitives.size() ||
            octree.references.size() + t_count > layout.primitives.size())
            fail("leaf " + std::to_string(index) + ": triangles out of range");
        cell.ref_begin = static_cast<std::uint32_t>(octree.references.size());
        for (std::uint64_t r = t_offset; r < t_offset + t_count; ++r)
            octree.references.push_back(layout.primitives[r].prim);
        cell.ref_end = static_cast<std::uint32_t>(octree.references.size());
    }
    return octree;
}

}  // namespace lancer::plucker
