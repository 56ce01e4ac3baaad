// The compressed wide BVH (src/cuda/cwbvh_*.hpp) on the CPU, against the bvh8 it is built from: its
// traversal gives bvh8's closest hits bit for bit (t, primitive, u, v) and its any-hit bvh8's occluded(), on
// port_test.cpp's scenes and rays with both triangle tests; its quantized boxes contain bvh8's boxes (and a
// split leaf's, its triangles); every leaf's triangles appear once, as bvh8 has them; the slots follow the
// octants. docs/cuda.md, "The compressed wide BVH".
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <random>

#include "accel/bvh/bvh_wide.hpp"
#include "cuda/cwbvh_build.hpp"
#include "cuda/cwbvh_traversal.hpp"
#include "port_scenes.hpp"

namespace lancer {
namespace {

using gpu::CompressedWideBvh;
using gpu::CwbvhNode;
using testing::BunnyCanonicalView;
using testing::TestScene;

bool contains(const Box3f& outer, const Box3f& inner) {
    for (int axis = 0; axis < 3; ++axis) {
        if (!(outer.lo[axis] <= inner.lo[axis] && outer.hi[axis] >= inner.hi[axis])) return false;
    }
    return true;
}

Box3f decoded_box(const CwbvhNode& node, int slot) {
    const float scale[3] = {gpu::quantization_scale(node.exponent[0]),
                            gpu::quantization_scale(node.exponent[1]),
                            gpu::quantization_scale(node.exponent[2])};
    return gpu::decoded_child_box(node, scale, slot);
}

bool is_inner(const CwbvhNode& node, int slot) {
    return ((node.inner_mask >> slot) & 1u) != 0;
}

std::uint32_t inner_child(const CwbvhNode& node, int slot) {
    return node.child_base + gpu::bit_count(node.inner_mask & ((1u << slot) - 1u));
}

// The structure against the bvh8 it was built from, walking both trees together. Every compressed node is
// reached once and every triangle reference once; each bvh8 child has one slot with the same primitives
// (an inner child for an inner child, a leaf or a split leaf for a leaf) whose decoded box contains bvh8's
// box; inside a split leaf each decoded box contains its triangles' box.
class StructureCheck {
  public:
    StructureCheck(const Bvh8Accel& bvh8, const Geometry& geometry, const CompressedWideBvh& compressed)
        : bvh8_(bvh8),
          geometry_(geometry),
          compressed_(compressed),
          node_reached_(compressed.nodes.size(), 0),
          reference_seen_(compressed.triangles.size(), 0) {}

    void run(const std::string& where) {
        where_ = where;
        ASSERT_EQ(compressed_.nodes.empty(), bvh8_.nodes().empty()) << where_;
        if (compressed_.nodes.empty()) return;
        std::size_t references = 0;
        for (const WideBvhNode<8>& node : bvh8_.nodes()) {
            for (int slot = 0; slot < 8; ++slot)
                references += node.prim_count[slot];
        }
        EXPECT_EQ(compressed_.triangles.size(), references) << where_;
        walk_matched(0, 0, 0);
        EXPECT_EQ(std::count(node_reached_.begin(), node_reached_.end(), 1), std::ssize(node_reached_))
            << where_;
        EXPECT_EQ(std::count(reference_seen_.begin(), reference_seen_.end(), 1), std::ssize(reference_seen_))
            << where_;
        EXPECT_EQ(deepest_, compressed_.max_depth) << where_;
        EXPECT_LE(compressed_.max_depth, gpu::kCwbvhStackSize) << where_;
    }

  private:
    struct Slot {
        Box3f box;
        bool inner = false;
        std::uint32_t index = 0;  // bvh8 or compressed node of an inner child
        std::vector<std::uint32_t> prims;
    };

    // A node's own invariants, and the primitives under each of its slots, sorted.
    std::vector<Slot> slots_of(std::uint32_t index, int depth) {
        const CwbvhNode& node = compressed_.nodes[index];
        ++node_reached_[index];
        deepest_ = std::max(deepest_, depth);
        std::vector<Slot> slots;
        std::uint32_t triangle_bits = 0;
        for (int slot = 0; slot < 8; ++slot) {
            if (gpu::is_empty_slot(node, slot)) continue;
            Slot entry{decoded_box(node, slot), is_inner(node, slot), inner_child(node, slot), {}};
            if (entry.inner) {
                EXPECT_LT(entry.index, compressed_.nodes.size()) << where_;
                entry.prims = prims_under(entry.index);
            } else {
                const std::uint32_t bits = gpu::leaf_triangle_bits(node.meta[slot]);
                const std::uint32_t offset = node.meta[slot] & 31u, count = (node.meta[slot] >> 5) + 1u;
                EXPECT_LE(offset + count, gpu::kMaxNodeTriangles) << where_;
                EXPECT_EQ(bits & triangle_bits, 0u) << where_ << ": leaves share a triangle bit";
                triangle_bits |= bits;
                for (std::uint32_t k = offset; k < offset + count; ++k) {
                    const std::size_t reference = node.triangle_base + k;
                    EXPECT_LT(reference, compressed_.triangles.size()) << where_;
                    if (reference >= compressed_.triangles.size()) continue;
                    ++reference_seen_[reference];
                    const gpu::TriangleRef& triangle = compressed_.triangles[reference];
                    EXPECT_EQ(std::memcmp(&triangle.triangle, &geometry_.triangles[triangle.prim],
                                          sizeof(Triangle)),
                              0)
                        << where_;
                    entry.prims.push_back(triangle.prim);
                }
            }
            std::sort(entry.prims.begin(), entry.prims.end());
            slots.push_back(std::move(entry));
        }
        return slots;
    }

    // The primitives under a compressed node, without counting it reached (prims_under is a look-ahead).
    std::vector<std::uint32_t> prims_under(std::uint32_t index) const {
        const CwbvhNode& node = compressed_.nodes[index];
        std::vector<std::uint32_t> prims;
        for (int slot = 0; slot < 8; ++slot) {
            if (gpu::is_empty_slot(node, slot)) continue;
            if (is_inner(node, slot)) {
                const std::vector<std::uint32_t> below = prims_under(inner_child(node, slot));
                prims.insert(prims.end(), below.begin(), below.end());
                continue;
            }
            for (std::uint32_t bits = gpu::leaf_triangle_bits(node.meta[slot]); bits != 0; bits &= bits - 1)
                prims.push_back(compressed_.triangles[node.triangle_base + gpu::lowest_bit(bits)].prim);
        }
        return prims;
    }

    std::vector<Slot> bvh8_children(std::uint32_t index) const {
        const WideBvhNode<8>& node = bvh8_.nodes()[index];
        std::vector<Slot> children;
        for (int slot = 0; slot < 8; ++slot) {
            if (node.is_empty(slot)) continue;
            Slot child{node.child_bounds(slot), node.prim_count[slot] == 0, node.child[slot], {}};
            std::vector<std::pair<std::uint32_t, int>> pending = {{index, slot}};
            while (!pending.empty()) {
                const auto [at, at_slot] = pending.back();
                pending.pop_back();
                const WideBvhNode<8>& n = bvh8_.nodes()[at];
                if (n.prim_count[at_slot] == 0) {
                    for (int s = 0; s < 8; ++s)
                        if (!bvh8_.nodes()[n.child[at_slot]].is_empty(s))
                            pending.push_back({n.child[at_slot], s});
                    continue;
                }
                const std::uint32_t first_block = leaf_span<8>(n.child[at_slot], n.prim_count[at_slot]).first;
                for (std::uint32_t i = 0; i < n.prim_count[at_slot]; ++i)
                    child.prims.push_back(bvh8_.blocks()[first_block + i / 8].prim[i % 8]);
            }
            std::sort(child.prims.begin(), child.prims.end());
            children.push_back(std::move(child));
        }
        return children;
    }

    void walk_matched(std::uint32_t compressed, std::uint32_t wide, int depth) {
        std::vector<Slot> slots = slots_of(compressed, depth);
        std::vector<bool> matched(slots.size(), false);
        for (const Slot& child : bvh8_children(wide)) {
            std::size_t found = slots.size();
            for (std::size_t s = 0; s < slots.size(); ++s) {
                if (matched[s] || slots[s].prims != child.prims || (child.inner && !slots[s].inner)) continue;
                if (found == slots.size() || contains(slots[s].box, child.box)) found = s;
            }
            ASSERT_LT(found, slots.size()) << where_ << ": no slot holds a bvh8 child's primitives";
            matched[found] = true;
            const Slot& slot = slots[found];
            EXPECT_TRUE(contains(slot.box, child.box)) << where_ << ": a decoded box lost its child's box";
            if (child.inner) {
                walk_matched(slot.index, child.index, depth + 1);
            } else if (slot.inner) {
                walk_split_leaf(slot.index, depth + 1);
            }
        }
        EXPECT_EQ(std::count(matched.begin(), matched.end(), true), std::ssize(slots)) << where_;
    }

    void walk_split_leaf(std::uint32_t compressed, int depth) {
        for (const Slot& slot : slots_of(compressed, depth)) {
            Box3f triangles;
            for (const std::uint32_t prim : slot.prims) {
                triangles.extend(geometry_.triangles[prim].v0);
                triangles.extend(geometry_.triangles[prim].v1);
                triangles.extend(geometry_.triangles[prim].v2);
            }
            EXPECT_TRUE(contains(slot.box, triangles)) << where_ << ": a split leaf's box lost a triangle";
            if (slot.inner) walk_split_leaf(slot.index, depth + 1);
        }
    }

    const Bvh8Accel& bvh8_;
    const Geometry& geometry_;
    const CompressedWideBvh& compressed_;
    std::vector<int> node_reached_, reference_seen_;
    int deepest_ = 0;
    std::string where_;
};

struct Agreement {
    std::size_t hits_seen = 0, split_leaves = 0;
    std::uint32_t largest_leaf = 0;  // bvh8's
};

// trace_cwbvh against bvh8 on every ray of `sets`: closest hits bit for bit, any-hit as occluded().
template <class TriangleTestT>
void expect_cwbvh_agrees(const Geometry& geometry, BuildOptions options,
                         std::span<const testing::RaySet> sets, const std::string& scene_name,
                         Agreement& agreement) {
    Bvh8Accel bvh8;
    bvh8.build(geometry, options);
    const CompressedWideBvh compressed = gpu::compress_bvh8(bvh8, bvh8.built_geometry());
    const gpu::CwbvhView view = compressed.view();
    agreement.split_leaves += compressed.split_leaves;
    for (const WideBvhNode<8>& node : bvh8.nodes()) {
        for (const std::uint32_t count : node.prim_count)
            agreement.largest_leaf = std::max(agreement.largest_leaf, count);
    }
    const std::string test_name = options.triangle_test == TriangleTest::Watertight ? "watertight" : "moller";
    StructureCheck(bvh8, bvh8.built_geometry(), compressed).run(scene_name + ", " + test_name);
    for (const testing::RaySet& set : sets) {
        const std::string where = scene_name + ", " + set.name + ", " + test_name + ": ";
        std::vector<Hit> expected(set.rays.size());
        bvh8.intersect(set.rays, expected);
        agreement.hits_seen += testing::count_hits(expected);
        const auto closest = testing::trace_each(set.rays, bvh8.bounds(), [&](const Ray& ray) {
            return gpu::trace_cwbvh<false, TriangleTestT>(view, ray);
        });
        std::string first;
        EXPECT_EQ(testing::count_differences(expected, closest, first), 0u)
            << where << "closest hit, " << first;

        std::vector<std::uint8_t> occluded(set.rays.size());
        bvh8.occluded(set.rays, occluded);
        const auto any = testing::occlusion_each(set.rays, bvh8.bounds(), [&](const Ray& ray) {
            return gpu::trace_cwbvh<true, TriangleTestT>(view, ray);
        });
        EXPECT_EQ(testing::count_differences(occluded, any), 0u) << where << "any hit against occluded()";
    }
}

// Triangles no split separates, which the SAH keeps in one leaf up to bvh.max_leaf_size: copies of one
// triangle, and triangles that share one box (each joins three corners of the same cube).
TestScene make_unsplittable_scene() {
    TestScene scene{"coincident triangles and triangles sharing a box", {}, {}};
    for (int copy = 0; copy < 45; ++copy)
        scene.triangles.push_back({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    for (int i = 0; i < 56; ++i) {
        const auto corner = [](int bits) {
            return Vec3f(3.0f + static_cast<float>(bits & 1), static_cast<float>((bits >> 1) & 1),
                         static_cast<float>((bits >> 2) & 1));
        };
        scene.triangles.push_back({corner(i % 8), corner(7 - i % 8), corner((i / 8 + i % 8 + 1) % 8)});
    }
    return scene;
}

void expect_agrees_on(std::span<const TestScene> scenes, int max_leaf_size, bool spatial_splits,
                      Agreement& agreement) {
    for (const TestScene& scene : scenes) {
        const std::vector<testing::RaySet> sets = testing::ray_sets_for(scene);
        for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
            BuildOptions options = build_options(test);
            options.group<BvhOptions>().max_leaf_size = max_leaf_size;
            options.group<BvhOptions>().spatial_splits = spatial_splits;
            if (test == TriangleTest::Watertight) {
                expect_cwbvh_agrees<Watertight>(scene.geometry(), options, sets, scene.name, agreement);
            } else {
                expect_cwbvh_agrees<MollerTrumbore>(scene.geometry(), options, sets, scene.name, agreement);
            }
        }
    }
}

TEST(Cwbvh, AgreesBitForBitWithBvh8OnTheTestScenes) {
    std::vector<TestScene> scenes = testing::make_triangle_scenes();
    scenes.push_back(make_unsplittable_scene());
    for (const bool spatial_splits : {false, true}) {
        Agreement agreement;
        expect_agrees_on(scenes, BvhOptions{}.max_leaf_size, spatial_splits, agreement);
        EXPECT_GT(agreement.hits_seen, 20000u);
        // Nodes whose leaves hold more than 32 triangles in all.
        EXPECT_GT(agreement.split_leaves, 0u);
    }
}

// bvh.max_leaf_size = 64: leaves of more than 8 triangles, each split into a node of its own, whose groups
// of 8 split again where they exceed 32 triangles in all.
TEST(Cwbvh, AgreesBitForBitWithLeavesOfUpTo64Triangles) {
    std::vector<TestScene> scenes = testing::make_triangle_scenes();
    scenes.push_back(make_unsplittable_scene());
    Agreement agreement;
    expect_agrees_on(scenes, 64, false, agreement);
    EXPECT_GT(agreement.hits_seen, 20000u);
    EXPECT_GT(agreement.largest_leaf, 32u);
}

TEST_F(BunnyCanonicalView, CwbvhAgreesBitForBit) {
    Agreement agreement;
    expect_cwbvh_agrees<MollerTrumbore>(geometry(), build_options(TriangleTest::MollerTrumbore), sets(),
                                        "bunny", agreement);
    expect_cwbvh_agrees<Watertight>(geometry(), build_options(TriangleTest::Watertight), sets(), "bunny",
                                    agreement);
    EXPECT_GT(agreement.hits_seen, 2u * kSide * kSide / 10u);
}

// Boxes the scenes do not make: far from the origin, flat, tiny beside huge, at the coordinate limit, sharing
// the frame's corner. Each decodes, with the traversal's decode, to a box that contains it.
TEST(Cwbvh, QuantizedBoxesContainTheirChildren) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::uniform_int_distribution<int> children(1, 8), power(-40, 58);
    const std::array<float, 6> offsets = {0.0f, 1.0f, -1e3f, 1e6f, -0x1p40f, 0x1p59f};
    std::size_t boxes_checked = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        const float offset = offsets[static_cast<std::size_t>(trial) % offsets.size()];
        const float size = std::ldexp(1.0f, power(rng));
        std::array<Box3f, gpu::kCwbvhWidth> boxes;
        const int count = children(rng);
        for (int c = 0; c < count; ++c) {
            // A child 2^-20 of the others' size one time in four; an axis flat one time in four.
            const float child_size = size * (unit(rng) < 0.25f ? 0x1p-20f : 1.0f);
            Box3f& box = boxes[static_cast<std::size_t>(c)];
            for (int axis = 0; axis < 3; ++axis) {
                const float lo = offset + size * unit(rng);
                box.lo[axis] = lo;
                box.hi[axis] = unit(rng) < 0.25f ? lo : lo + child_size * unit(rng);
            }
        }
        CwbvhNode node{};
        gpu::quantize_child_boxes(boxes, node);
        for (int slot = 0; slot < gpu::kCwbvhWidth; ++slot) {
            if (slot >= count) {
                EXPECT_EQ(node.lo[0][slot] | node.lo[1][slot] | node.lo[2][slot] | node.hi[0][slot] |
                              node.hi[1][slot] | node.hi[2][slot],
                          0);
                continue;
            }
            const Box3f& box = boxes[static_cast<std::size_t>(slot)];
            ASSERT_TRUE(contains(decoded_box(node, slot), box))
                << "trial " << trial << ", slot " << slot << ", offset " << offset << ", size " << size;
            ++boxes_checked;
        }
    }
    EXPECT_GT(boxes_checked, 80000u);
}

// Bounds a hair from a grid line, far from the frame's origin: their difference to the origin rounds in
// double onto the grid line and the exact-arithmetic q lands one step outside the box, which the check
// against the traversal's decode moves back, without a coarser grid.
TEST(Cwbvh, QuantizedBoundsAHairFromAGridLineStayOutside) {
    for (int power = 20; power <= 59; ++power) {
        for (const float hair : {0x1p-30f, 1e-5f, 3e-3f}) {
            const float far = std::ldexp(1.0f, power);
            std::array<Box3f, gpu::kCwbvhWidth> boxes;
            for (std::size_t slot = 0; const float at : {-far, -hair, hair, far})
                boxes[slot++] = {Vec3f(at), Vec3f(at)};
            CwbvhNode node{};
            gpu::quantize_child_boxes(boxes, node);
            for (int slot = 0; slot < 4; ++slot) {
                EXPECT_TRUE(contains(decoded_box(node, slot), boxes[static_cast<std::size_t>(slot)]))
                    << "2^" << power << ", " << hair << ", slot " << slot;
            }
            // The finest grid whose 255 steps span the frame's 2 far.
            for (int axis = 0; axis < 3; ++axis)
                EXPECT_LT(gpu::kQuantizationSteps * std::ldexp(1.0, node.exponent[axis] - 1), 2.0 * far);
        }
    }
}

// The robust slab test enters a decoded box whenever it enters the child's box (the decoded box contains it
// and every plane distance is monotonic in its bound): rays aimed at points of the box, along its faces and
// along the axes, near the origin and far from it.
TEST(Cwbvh, DecodedBoxesAreEnteredWheneverTheirChildrenAre) {
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    std::size_t entered = 0, lost = 0;
    for (int trial = 0; trial < 2000; ++trial) {
        const float offset = trial % 2 == 0 ? 0.0f : 0x1p30f;
        std::array<Box3f, gpu::kCwbvhWidth> boxes;
        for (Box3f& box : boxes) {
            for (int axis = 0; axis < 3; ++axis) {
                box.lo[axis] = offset + unit(rng);
                box.hi[axis] = box.lo[axis] + (unit(rng) < 0.2f ? 0.0f : 0.3f * unit(rng));
            }
        }
        CwbvhNode node{};
        gpu::quantize_child_boxes(boxes, node);
        for (int slot = 0; slot < gpu::kCwbvhWidth; ++slot) {
            const Box3f& box = boxes[static_cast<std::size_t>(slot)];
            const Box3f decoded = decoded_box(node, slot);
            for (int r = 0; r < 16; ++r) {
                // A point of the box, on a face one time in two; the ray from outside through it, one time in
                // four along an axis.
                Vec3f target;
                for (int axis = 0; axis < 3; ++axis)
                    target[axis] = box.lo[axis] + (box.hi[axis] - box.lo[axis]) * unit(rng);
                if (r % 2 == 0) target[r % 3] = r % 4 == 0 ? box.lo[r % 3] : box.hi[r % 3];
                Vec3f direction(unit(rng) - 0.5f, unit(rng) - 0.5f, unit(rng) - 0.5f);
                if (r % 4 == 1) direction = {0.0f, 0.0f, 0.0f}, direction[r % 3] = 1.0f;
                const Ray ray{target - 2.0f * direction, direction, 0.0f, kInfinity};
                const SlabRay slab(ray);
                float entry, exit;
                if (!intersect_box(slab, box, ray.tnear, ray.tfar, entry, exit)) continue;
                ++entered;
                lost += intersect_box(slab, decoded, ray.tnear, ray.tfar, entry, exit) ? 0 : 1;
            }
        }
    }
    EXPECT_GT(entered, 100000u);
    EXPECT_EQ(lost, 0u);
}

// Eight clusters of triangles, one per octant: the root's slot s holds the cluster on the + side of axis a
// where bit 2 - a of s is set, and a ray from each corner visits the cluster at that corner first.
TEST(Cwbvh, SlotsFollowTheOctants) {
    TestScene clusters{"a cluster per octant", {}, {}};
    for (int octant = 0; octant < 8; ++octant) {
        const Vec3f center((octant & 4) != 0 ? 4.0f : -4.0f, (octant & 2) != 0 ? 4.0f : -4.0f,
                           (octant & 1) != 0 ? 4.0f : -4.0f);
        make_icosphere(2, center, 1.0f).append_triangles(clusters.triangles);
    }
    Bvh8Accel bvh8;
    bvh8.build(clusters.geometry(), {});
    const CompressedWideBvh compressed = gpu::compress_bvh8(bvh8, bvh8.built_geometry());
    const CwbvhNode& root = compressed.nodes[0];
    ASSERT_EQ(root.inner_mask, 0xFF);
    for (int slot = 0; slot < 8; ++slot) {
        const Vec3f center = decoded_box(root, slot).center();
        EXPECT_EQ(center.x > 0.0f, (slot & 4) != 0) << slot;
        EXPECT_EQ(center.y > 0.0f, (slot & 2) != 0) << slot;
        EXPECT_EQ(center.z > 0.0f, (slot & 1) != 0) << slot;
    }
    for (int corner = 0; corner < 8; ++corner) {
        // From the corner's side towards the opposite one: the first slot visited is the corner's.
        const Vec3f direction((corner & 4) != 0 ? -1.0f : 1.0f, (corner & 2) != 0 ? -1.0f : 1.0f,
                              (corner & 1) != 0 ? -1.0f : 1.0f);
        const std::uint32_t swizzle = gpu::octant_swizzle(direction);
        int first = 0;
        for (int slot = 0; slot < 8; ++slot)
            if ((static_cast<std::uint32_t>(slot) ^ swizzle) > (static_cast<std::uint32_t>(first) ^ swizzle))
                first = slot;
        EXPECT_EQ(first, corner);
    }
}

TEST(Cwbvh, RefusesSpheres) {
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const std::vector<Sphere> spheres = {{{0, 0, 2}, 0.5f, 0}};
    const Geometry with_spheres{triangles, spheres};
    Bvh8Accel bvh8;
    bvh8.build(with_spheres, {});
    EXPECT_THROW((void)gpu::compress_bvh8(bvh8, with_spheres), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
