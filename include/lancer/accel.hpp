// The one interface every acceleration structure implements (build / closest hit / any hit / stats / memory).
// Virtual dispatch happens once per batch of rays, never per node.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lancer/box.hpp"
#include "lancer/isa.hpp"
#include "lancer/packet.hpp"
#include "lancer/ray.hpp"
#include "lancer/scene.hpp"

namespace lancer {

enum class TriangleTest {
    MollerTrumbore,  // Moller & Trumbore 1997 (seeds 003, 004): fast, may leak through shared edges
    Watertight,      // Woop, Benthin & Wald 2013: no ray passes between two triangles that share an edge
};

// Regular grid (seed 004): cells per axis = density * cbrt(N), shared among the axes in proportion to the
// box's extents, so that cells are about cubic.
struct GridOptions {
    float density = 1.0f;
};

// Classic octree (seed 004; Revelles et al. 2000): a node is split while depth < max_depth and it holds
// more than leaf_size references.
struct OctreeOptions {
    int max_depth = 10;
    int leaf_size = 8;
};

// Pluecker-connected octree (seed 000, Portalez & Duguet 2016): the octree above with the 2:1 rule and
// face-neighbour links, walked leaf to leaf. max_depth 0 = automatic: round(0.8 log2(N) - 5), the depths of
// the seed's section 5.2 (8 for the bunny's 69k triangles, 10 for the armadillo's 346k, 11 for the
// dragon's 871k). The other fields are the variants of its section 6 (docs/plucker-octree.md).
struct PluckerOptions {
    int max_depth = 0;
    // Split while a cell holds more references. 32, not the seed's 12 ("6 triangles per leaf on average",
    // 5.1): leaves are tested 8 triangles per block here, so larger leaves cost few extra tests and save
    // steps, memory and build time (docs/plucker-octree.md, "Leaf size"); the seed's tables use 12.
    int leaf_size = 32;
    bool balanced = true;      // false: no 2:1 rule, links to the same-or-larger neighbour and a descent
    bool stored_boxes = true;  // false: cell planes recomputed from integer coordinates and level
    bool morton = false;       // true: cells in depth-first (Morton) order instead of the build's order
};

enum class KdTreeCost {
    WaldHavran,  // Wald & Havran 2006: SAH with an empty-space bonus
    Seed003,     // seed 003 section 5.3.2: C = 1 / SA(N) [SA(L)(Nl + Nb) + SA(R)(Nr + Nb)], no bonus
};

// SAH kd-tree (Wald & Havran 2006). max_depth 0 = automatic: 8 + 1.3 log2(N).
struct KdTreeOptions {
    KdTreeCost cost = KdTreeCost::WaldHavran;
    float traversal_cost = 15.0f;
    float intersection_cost = 20.0f;
    // Cost factor (1 - bonus) when a side is empty: Wald & Havran's lambda = 0.8, a 20% bonus. A bonus of 0.8
    // (factor 0.2) spends the depth limit on thin empty slabs: 1.6x the SAH cost and 6x the primitive tests
    // per ray on the armadillo (docs/accel/kdtree.md).
    float empty_bonus = 0.2f;
    int max_depth = 0;
};

enum class BvhBuilder {
    SweepSah,   // seed 002: full sweep over centroids sorted on each axis
    BinnedSah,  // Wald 2007: binned SAH, parallel over oneTBB when available
};

struct BvhOptions {
    BvhBuilder builder = BvhBuilder::BinnedSah;
    int max_leaf_size = 4;
    int bins = 32;
    // Spatial splits (Stich, Friedrich & Dietrich 2009, the SBVH) in the binned builder: a node may also
    // be split by a plane that cuts references in two, a primitive then appearing in several leaves, within
    // a budget of references (docs/accel/bvh.md, "Spatial splits"). The sweep builder ignores it.
    bool spatial_splits = false;
};

// Embree's build quality for the `embree` structures: HIGH (with spatial splits, its best trace speed) or
// MEDIUM (the faster build).
enum class EmbreeQuality { High, Medium };

struct BuildOptions {
    TriangleTest triangle_test = TriangleTest::MollerTrumbore;
    GridOptions grid;
    OctreeOptions octree;
    PluckerOptions plucker;
    KdTreeOptions kdtree;
    BvhOptions bvh;
    EmbreeQuality embree_quality = EmbreeQuality::High;
    // The instruction set of the kernels built for more than one (lancer/isa.hpp): today bvh8_packet's.
    SimdIsa isa = SimdIsa::Auto;
};

// Sets one option from "KEY=VALUE", as `--set` gives it; build_option_infos() lists the keys. Throws
// std::invalid_argument naming the key and the values it accepts.
void set_build_option(BuildOptions& options, std::string_view assignment);

// One key of set_build_option: what it sets, the values it accepts and its default.
struct BuildOptionInfo {
    std::string key;  // "bvh.builder"
    std::string accepted;
    std::string default_value;
    std::string help;
};
// Every key, grouped by structure (what `lancer info --options` prints).
[[nodiscard]] std::vector<BuildOptionInfo> build_option_infos();

// Defaults with the given triangle test (brace-initialising the aggregate would leave the rest to -Wextra).
[[nodiscard]] inline BuildOptions build_options(TriangleTest test) {
    BuildOptions options;
    options.triangle_test = test;
    return options;
}

// Statistics of a built structure (seed 003's counts; every field a structure does not have stays 0).
struct AccelStats {
    double build_ms = 0.0;
    std::size_t primitives = 0;
    std::size_t nodes = 0;  // inner nodes and leaves, or cells
    std::size_t leaves = 0;
    std::size_t empty_leaves = 0;
    std::size_t references = 0;  // primitive references stored in leaves (duplicates included)
    int max_depth = 0;
    double mean_depth = 0.0;
    double mean_refs_per_leaf = 0.0;
    std::size_t max_refs_per_leaf = 0;
    double sah_cost = 0.0;
    std::vector<std::pair<std::string, std::size_t>> memory_by_array;  // bytes, trace-time arrays only
};

// Per-ray work counters, summed over a batch. Structures count only when handed a non-null pointer, and the
// counting code is a template branch chosen once per batch, so the fast path pays nothing.
struct TraversalCounters {
    std::uint64_t rays = 0;
    std::uint64_t nodes_visited = 0;  // inner nodes, leaves or cells entered
    std::uint64_t prims_tested = 0;

    TraversalCounters& operator+=(const TraversalCounters& o) {
        rays += o.rays, nodes_visited += o.nodes_visited, prims_tested += o.prims_tested;
        return *this;
    }
};

class Accel {
  public:
    virtual ~Accel() = default;

    [[nodiscard]] virtual std::string_view name() const = 0;
    // The structure may keep the spans of `geometry`: the caller keeps them alive and unchanged. Throws
    // std::invalid_argument when a coordinate lies outside the contract's domain (kCoordinateLimit).
    void build(const Geometry& geometry, const BuildOptions& options);
    // Closest hit of each ray in [tnear, tfar]; hits.size() == rays.size(). Invalid rays miss (is_valid).
    // Rays are first conditioned the same way for every structure (docs/numerical-contract.md, "Ray
    // conditioning"): extreme directions scaled by a power of two, far rays moved near the scene.
    void intersect(std::span<const Ray> rays, std::span<Hit> hits,
                   TraversalCounters* counters = nullptr) const;
    // The same answers, for a batch the caller knows to be coherent: camera rays from neighbouring pixels,
    // every 16 consecutive rays a 4x4 pixel block and every 8 a 4x2 one (lancer bench's tile order). A
    // structure with a kernel of its own for such rays uses it (Embree's COHERENT flag); the others trace
    // them as any batch.
    void intersect_coherent(std::span<const Ray> rays, std::span<Hit> hits,
                            TraversalCounters* counters = nullptr) const;
    // The closest hits of a packet's rays, lanes [0, rays.size), the same as intersect()'s bit for bit; the
    // hits' lanes from rays.size on are unspecified. The fastest call for coherent rays: a structure with a
    // packet kernel (bvh8_packet, embree16) reads the rays in place. Throws std::invalid_argument for a size
    // outside [0, RayPacket::kMaxSize].
    void intersect_packet(const RayPacket& rays, HitPacket& hits,
                          TraversalCounters* counters = nullptr) const;
    // Any hit in [tnear, tfar]: occluded[i] = 1 when ray i hits something, 0 otherwise.
    void occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                  TraversalCounters* counters = nullptr) const;
    // The box of the primitives that can be hit, as built (empty before): what makes a ray's origin far.
    [[nodiscard]] const Box3f& bounds() const { return bounds_; }
    [[nodiscard]] virtual AccelStats stats() const = 0;
    // Bytes the structure itself needs at trace time, the geometry it was built on excluded.
    [[nodiscard]] virtual std::size_t memory_bytes() const = 0;

  protected:
    virtual void build_structure(const Geometry& geometry, const BuildOptions& options) = 0;
    virtual void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                 TraversalCounters* counters) const = 0;
    virtual void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                TraversalCounters* counters) const = 0;
    virtual void intersect_coherent_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                          TraversalCounters* counters) const {
        intersect_batch(rays, hits, counters);
    }
    // A packet none of whose rays needs conditioning. By default its rays go through intersect_coherent_batch
    // as a batch of `Ray` records.
    virtual void intersect_packet_rays(const RayPacket& rays, HitPacket& hits,
                                       TraversalCounters* counters) const;
    // What build does before build_structure, for a structure that gets its arrays another way (a file):
    // checks the domain and records the scene's box for far rays.
    void accept_geometry(const Geometry& geometry);

  private:
    Box3f bounds_;
};

// intersect() and occluded() on `threads` threads (0: all, or those of the oneTBB arena the caller runs in),
// in tasks of 4096 consecutive rays: large enough to amortise a batch call, small enough to balance cores on
// uneven rays. The same answers as one call; without oneTBB, one call.
void intersect_parallel(const Accel& accel, std::span<const Ray> rays, std::span<Hit> hits, int threads = 0);
void occluded_parallel(const Accel& accel, std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                       int threads = 0);

// The names `--accel` accepts, in the order `lancer bench --accel all` measures them.
[[nodiscard]] std::vector<std::string_view> accel_names();
// The same with a line on each (what `lancer info --options` prints).
struct AccelInfo {
    std::string_view name;
    std::string_view summary;
};
[[nodiscard]] std::vector<AccelInfo> accel_infos();
// A new, unbuilt structure; throws std::invalid_argument naming the known structures for an unknown name.
[[nodiscard]] std::unique_ptr<Accel> make_accel(std::string_view name);

}  // namespace lancer
