// The numbering of faces, vertices and sub-faces of a cell of the Plücker octree, and the lookup tables of
// Portalez & Duguet 2016, section 4.2 (equations 6 to 10) derived from it at compile time: the seed's Figure
// 4, which fixes its own numbering, is missing, so its tables (7), (8) and (9) cannot be copied. Derivation
// and conventions: docs/accel/plucker.md; tests/accel/plucker/plucker_tables_test.cpp checks the tables
// against slab computations.
#pragma once

#include <array>
#include <cstdint>

namespace lancer::plucker {

// The octree build's conventions (octree_build.hpp): axis 0 = x, 1 = y, 2 = z; face 2 axis + side, side 1 the
// upper face (0 -x, 1 +x, 2 -y, 3 +y, 4 -z, 5 +z); vertex: bit a set for the upper coordinate on axis a (the
// build's child order); octant: the exit vertex of a ray, bit a set when it moves towards +a (a zero
// component is given a sign per ray, walk.hpp, and never wins an exit); sub-face on a face with in-face axes
// u < v: bit_u | bit_v << 1, bit 1 the upper half, the order of the four finer neighbours across a face.
[[nodiscard]] constexpr int face_axis(int face) {
    return face >> 1;
}
[[nodiscard]] constexpr int face_side(int face) {
    return face & 1;
}
[[nodiscard]] constexpr int make_face(int axis, int side) {
    return 2 * axis + side;
}
// The in-face axes of a face normal to `axis`, in increasing order (the sub-face bits).
[[nodiscard]] constexpr int lower_in_face_axis(int axis) {
    return axis == 0 ? 1 : 0;
}
[[nodiscard]] constexpr int upper_in_face_axis(int axis) {
    return axis == 2 ? 1 : 2;
}

namespace derivation {

// Exact 3-vectors of small integers: the sample rays below are built so that every Plücker product is an
// integer, hence exact, and its sign is the one of equation (2).
struct IntVec {
    long long c[3];
};

// The permuted inner product of the ray (o, d) with the line through p along +e_axis (Portalez & Duguet 2016,
// eq. 2 with the simplification of eq. 4-5): Pi_axis(p) = d . ((p - o) x e_axis) = (d x (p - o))_axis.
[[nodiscard]] constexpr long long pluecker(const IntVec& o, const IntVec& d, const IntVec& p, int axis) {
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    return d.c[a1] * (p.c[a2] - o.c[a2]) - d.c[a2] * (p.c[a1] - o.c[a1]);
}

// Equation (6): the three signs packed, bit a = [Pi_a > 0].
[[nodiscard]] constexpr int sign_pattern(const IntVec& o, const IntVec& d, const IntVec& p) {
    int pattern = 0;
    for (int axis = 0; axis < 3; ++axis)
        pattern |= (pluecker(o, d, p, axis) > 0 ? 1 : 0) << axis;
    return pattern;
}

inline constexpr int kUnset = -1;
// The cell of the samples: [0, kCell]^3.
inline constexpr long long kCell = 8;

// Equations (7)-(8): for every octant, every strict order of the three slab exits t_x, t_y, t_z gives a
// sample ray through the cell that leaves it first on the axis ranked first; its sign pattern indexes the
// exit face. Two patterns of the eight are cyclic (no order of three numbers gives them); rounding can
// produce them only when the three exits are within rounding of each other (the ray passes by the exit
// vertex), where any of the three exit faces is right: they map to the exit face on x.
struct ExitTables {
    std::array<std::array<std::uint8_t, 8>, 8> face{};
    std::array<std::array<bool, 8>, 8> derived{};  // false for the two cyclic patterns of each octant
};

[[nodiscard]] constexpr ExitTables derive_exit_tables() {
    ExitTables tables;
    constexpr int kOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int octant = 0; octant < 8; ++octant) {
        std::array<int, 8> face;
        face.fill(kUnset);
        for (const auto& order : kOrders) {
            // rank[axis]: 1, 2, 3 in the order of exit; the ray leaves plane `axis` at t = rank[axis].
            long long rank[3] = {};
            for (int position = 0; position < 3; ++position)
                rank[order[position]] = position + 1;
            IntVec d{}, o{}, vertex{};
            for (int axis = 0; axis < 3; ++axis) {
                const bool up = (octant >> axis) & 1;
                vertex.c[axis] = up ? kCell : 0;
                d.c[axis] = up ? 1 : -1;
                o.c[axis] = vertex.c[axis] - rank[axis] * d.c[axis];  // o + rank d reaches the exit plane
            }
            const int pattern = sign_pattern(o, d, vertex);
            if (face[static_cast<std::size_t>(pattern)] != kUnset) throw "two exit orders share a pattern";
            const int exit_axis = order[0];
            face[static_cast<std::size_t>(pattern)] = make_face(exit_axis, (octant >> exit_axis) & 1);
        }
        for (int pattern = 0; pattern < 8; ++pattern) {
            const auto p = static_cast<std::size_t>(pattern);
            tables.derived[static_cast<std::size_t>(octant)][p] = face[p] != kUnset;
            tables.face[static_cast<std::size_t>(octant)][p] =
                static_cast<std::uint8_t>(face[p] != kUnset ? face[p] : make_face(0, octant & 1));
        }
    }
    return tables;
}

// Equations (9)-(10): on face f, a ray leaving the cell through sub-face q gives, against the two median
// lines of the face (through its centre P, along the in-face axes), a sign pattern that indexes q. The bit
// of the face's normal axis (the line along the normal) carries no information: both of its values map to
// the same sub-face. The table does not depend on the in-face direction components (all four sign
// combinations give the same pattern) nor on the octant: the sign of the normal component is the face's.
struct NeighbourTables {
    std::array<std::array<std::uint8_t, 8>, 6> quadrant{};
    // tie[f][octant]: the bit to use for an in-face component whose product is exactly 0 (the ray crosses
    // the face on a median line), so that the sub-face chosen is the one on the octant's side of that
    // median. For a zero direction component this keeps the walk in cells whose exit plane is not the
    // ray's own coordinate (docs/accel/plucker.md, "Zero direction components"); otherwise either side is
    // right.
    std::array<std::array<std::uint8_t, 8>, 6> tie{};
};

[[nodiscard]] constexpr NeighbourTables derive_neighbour_tables() {
    NeighbourTables tables;
    for (int face = 0; face < 6; ++face) {
        const int normal = face_axis(face), side = face_side(face);
        const int u = lower_in_face_axis(normal), v = upper_in_face_axis(normal);
        std::array<int, 8> quadrant;
        quadrant.fill(kUnset);
        for (int q = 0; q < 4; ++q) {
            for (int in_face_signs = 0; in_face_signs < 4; ++in_face_signs) {
                // The ray crosses the face at the centre of sub-face q at t = 1.
                IntVec crossing{}, d{}, centre{};
                crossing.c[normal] = side ? kCell : 0;
                crossing.c[u] = (q & 1) ? 3 * kCell / 4 : kCell / 4;
                crossing.c[v] = (q & 2) ? 3 * kCell / 4 : kCell / 4;
                d.c[normal] = side ? 4 : -4;
                d.c[u] = (in_face_signs & 1) ? 1 : -1;
                d.c[v] = (in_face_signs & 2) ? 1 : -1;
                IntVec o{};
                for (int axis = 0; axis < 3; ++axis)
                    o.c[axis] = crossing.c[axis] - d.c[axis];
                centre.c[normal] = crossing.c[normal];
                centre.c[u] = kCell / 2;
                centre.c[v] = kCell / 2;
                const int pattern = sign_pattern(o, d, centre);
                for (int normal_bit = 0; normal_bit < 2; ++normal_bit) {
                    const auto index =
                        static_cast<std::size_t>((pattern & ~(1 << normal)) | normal_bit << normal);
                    if (quadrant[index] != kUnset && quadrant[index] != q) throw "sub-face patterns collide";
                    quadrant[index] = q;
                }
            }
        }
        for (int pattern = 0; pattern < 8; ++pattern) {
            if (quadrant[static_cast<std::size_t>(pattern)] == kUnset) throw "a sub-face pattern is missing";
            tables.quadrant[static_cast<std::size_t>(face)][static_cast<std::size_t>(pattern)] =
                static_cast<std::uint8_t>(quadrant[static_cast<std::size_t>(pattern)]);
        }
        // The product against the line along u decides the v bit, and conversely. For each, the tie bit is
        // the value whose sub-face lies on the octant's side of the median.
        for (int octant = 0; octant < 8; ++octant) {
            int tie = 0;
            for (const auto& [component, decided, decided_bit] : {std::array{u, v, 1}, std::array{v, u, 0}}) {
                const int wanted = (octant >> decided) & 1;
                for (int bit = 0; bit < 2; ++bit) {
                    const int q = quadrant[static_cast<std::size_t>(bit << component)];
                    if (((q >> decided_bit) & 1) == wanted) tie |= bit << component;
                }
            }
            tables.tie[static_cast<std::size_t>(face)][static_cast<std::size_t>(octant)] =
                static_cast<std::uint8_t>(tie);
        }
    }
    return tables;
}

}  // namespace derivation

inline constexpr derivation::ExitTables kExitTables = derivation::derive_exit_tables();
inline constexpr derivation::NeighbourTables kNeighbourTables = derivation::derive_neighbour_tables();

// outFacesLookup of equation (8), in this file's numbering: kExitFace[octant][pattern].
inline constexpr std::array<std::array<std::uint8_t, 8>, 8> kExitFace = kExitTables.face;
// faceToNeighborIndex of equation (9): kNeighbourQuadrant[face][pattern].
inline constexpr std::array<std::array<std::uint8_t, 8>, 6> kNeighbourQuadrant = kNeighbourTables.quadrant;
inline constexpr std::array<std::array<std::uint8_t, 8>, 6> kQuadrantTieBits = kNeighbourTables.tie;

// Every exit face lies on the octant's side: the walk always moves with the ray (termination rests on it).
static_assert([] {
    for (int octant = 0; octant < 8; ++octant) {
        for (int pattern = 0; pattern < 8; ++pattern) {
            const int face = kExitFace[static_cast<std::size_t>(octant)][static_cast<std::size_t>(pattern)];
            if (face_side(face) != ((octant >> face_axis(face)) & 1)) return false;
        }
    }
    return true;
}());

}  // namespace lancer::plucker
