// The one interface every acceleration structure implements (build / closest hit / any hit / stats / memory).
// Virtual dispatch happens once per batch of rays, never per node.
#pragma once

#include <any>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
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
    MollerTrumbore,  // Moller & Trumbore 1997 (Ferreira & Mendoza 2011, 3): fast, may leak at shared edges
    Watertight,      // Woop, Benthin & Wald 2013: no ray passes between two triangles that share an edge
};

// The options of a build: what every structure shares (the triangle test, the instruction set), and each
// structure's own group, a struct declared in its folder with a name (`static constexpr std::string_view
// kGroup = "bvh";`) and its defaults, kept here by that name so that this header names no structure. Code
// that includes a structure's header reaches its group by type; everyone else by `--set` key
// (set_build_option, build_option_infos).
class BuildOptions {
  public:
    TriangleTest triangle_test = TriangleTest::MollerTrumbore;
    // The instruction set of the kernels built for more than one (lancer/isa.hpp): today bvh8_packet's.
    SimdIsa isa = SimdIsa::Auto;

    // Group's options, its defaults until one is set.
    template <class Group>
    [[nodiscard]] Group& group() {
        std::any& slot = groups_[std::string(Group::kGroup)];
        if (!slot.has_value()) slot = Group{};
        return std::any_cast<Group&>(slot);
    }
    template <class Group>
    [[nodiscard]] const Group& group() const {
        static const Group defaults{};
        const auto found = groups_.find(Group::kGroup);
        return found == groups_.end() ? defaults : std::any_cast<const Group&>(found->second);
    }

  private:
    std::map<std::string, std::any, std::less<>> groups_;
};

// Sets one option from "KEY=VALUE", as `--set` gives it; build_option_infos() lists the keys. Throws
// std::invalid_argument naming the key and the values it accepts.
void set_build_option(BuildOptions& options, std::string_view assignment);
// The value of one key in `options`, as set_build_option reads it. Throws std::invalid_argument naming the
// known keys for an unknown one.
[[nodiscard]] std::string build_option_value(const BuildOptions& options, std::string_view key);

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

// One figure of a built structure's statistics, named and explained by the structure itself: `lancer stats`,
// its JSON and the Python module's stats() list a structure's figures as it gives them, so that a structure
// reports what it has (a grid its cells, a tree its depth, Embree none) without a field here for each.
struct AccelFigure {
    std::string key;  // snake_case: the JSON's and Python's key
    double value = 0.0;
    bool whole = false;  // a count, printed without decimals
    std::string help;    // what it measures, one phrase
};

// Statistics of a built structure (the counts of Ferreira & Mendoza 2011).
struct AccelStats {
    double build_ms = 0.0;
    std::size_t primitives = 0;
    std::vector<AccelFigure> figures;                                  // the structure's own, in its order
    std::vector<std::pair<std::string, std::size_t>> memory_by_array;  // bytes, trace-time arrays only

    // The figure named `key`, or null where the structure has none.
    [[nodiscard]] const AccelFigure* find(std::string_view key) const;
    // The figure's value; throws std::out_of_range naming the key where the structure has no such figure.
    [[nodiscard]] double value(std::string_view key) const;
    // The same for a count; throws std::invalid_argument naming the key where the figure is not one.
    [[nodiscard]] std::size_t count(std::string_view key) const;
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

// How a structure follows its triangles when they move (Accel::update).
enum class UpdateMethod {
    Rebuild,  // builds itself again on the moved triangles
    // Keeps its tree and recomputes its boxes bottom-up (Wald, Boulos & Shirley 2007, "Ray tracing
    // deformable scenes using dynamic bounding volume hierarchies"), rebuilding when the tree has degraded
    // past a threshold (docs/accel/refit.md).
    Refit,
};

// What one Accel::update did.
struct UpdateReport {
    UpdateMethod method = UpdateMethod::Rebuild;  // a refitting structure rebuilds past its threshold
    double ms = 0.0;  // the whole update: the checks, and World::update_vertices's copy and flattening
    double structure_ms = 0.0;  // the structure's own part of it: the refit or the rebuild
    // SAH cost of the tree as it now is over its cost when it was last built (the `sah_ratio` figure): 1
    // after a rebuild, and for the structures without an SAH cost.
    double sah_ratio = 1.0;
};

class Accel;
class World;
class CudaTracer;
class GeometryQueries;
class InstancedScene;
class BvhAccel;
namespace plucker {
struct PluckerLayout;
}

// One valid ray through a single-ray structure's own walk (SingleRayAccel's trace), without the batch call
// around it: its loop over the rays, validity test and dispatch of the triangle test. For InstancedScene,
// whose instance visits trace one ray a call (docs/accel/instances.md). closest improves `best` by
// lancer::closer, any returns whether anything is hit; both add to the counters when they are given.
struct SingleRayWalk {
    void (*closest)(const Accel& structure, const Ray& ray, Hit& best, TraversalCounters* counters) = nullptr;
    bool (*any)(const Accel& structure, const Ray& ray, TraversalCounters* counters) = nullptr;
};

// The arrays of a structure that other code reads as they are: the GPU tracer uploads a binary BVH or a
// Plücker octree (CudaTracer), a `.plo` file stores a Plücker octree (World::save_structure). A structure
// names the ones it has; the others are null.
struct ExportedLayout {
    const BvhAccel* bvh = nullptr;
    const plucker::PluckerLayout* plucker = nullptr;
    // A packet structure's single-ray structure, whose arrays its packets trace as they are (bvh8_packet's
    // bvh8): what GeometryQueries walks for the packet structure. It holds the packet structure's built
    // geometry at scale 1, so rays reach it conditioned at the packet structure's scale_exponent().
    const Accel* single_ray = nullptr;
};

class Accel {
  public:
    virtual ~Accel() = default;

    [[nodiscard]] virtual std::string_view name() const = 0;
    // The structure may keep the spans of `geometry`: the caller keeps them alive and unchanged. Throws
    // std::invalid_argument when a coordinate lies outside the contract's domain (kCoordinateLimit).
    void build(const Geometry& geometry, const BuildOptions& options);
    // Follows triangles that moved while the primitives stayed the same: `geometry` has as many triangles
    // and spheres as the geometry of the last build, in the same order, and replaces it (the same spans
    // rewritten in place, or others). The BVHs refit, the other structures rebuild (update_method). Throws
    // std::invalid_argument, the structure left as it was, for other counts or a coordinate outside the
    // contract's domain; the caller then restores the geometry the structure was built on before tracing.
    UpdateReport update(const Geometry& geometry);
    // What update does with this structure as built.
    [[nodiscard]] virtual UpdateMethod update_method() const { return UpdateMethod::Rebuild; }
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
    // The box of the primitives that can be hit, as built (empty before), in the caller's units: what makes a
    // ray's origin far.
    [[nodiscard]] const Box3f& bounds() const { return bounds_; }
    // The geometry the structure was built on, whose arrays it holds (ExportedLayout): the caller's, or, for
    // a scene whose largest side lies outside [2^-20, 2^20], a copy scaled by 2^scale_exponent(), a power of
    // two that brings it into [1/2, 1), where no product of the kernels overflows or underflows
    // (docs/numerical-contract.md, "Coordinate domain"). Rays are scaled with it before the structure sees
    // them, and their hits' t mapped back.
    [[nodiscard]] const Geometry& built_geometry() const { return built_geometry_; }
    [[nodiscard]] int scale_exponent() const { return scale_exponent_; }
    [[nodiscard]] virtual AccelStats stats() const = 0;
    // Bytes the structure itself needs at trace time, the geometry it was built on excluded.
    [[nodiscard]] virtual std::size_t memory_bytes() const = 0;

  protected:
    virtual void build_structure(const Geometry& geometry, const BuildOptions& options) = 0;
    // update's work once the geometry is checked.
    virtual UpdateReport update_structure(const Geometry& geometry) = 0;
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
    // checks the domain, records the scene's box for far rays and the primitive counts for update, and makes
    // the geometry the structure is built on (built_geometry).
    void accept_geometry(const Geometry& geometry);
    // The box of built_geometry's primitives that can be hit: the one a structure derives its own sizes from.
    [[nodiscard]] const Box3f& built_bounds() const { return built_bounds_; }
    // build() of a structure this one is made of (a packet structure's single-ray one) on this one's built
    // geometry, which it sees at scale 1 as it sees the rays this one scales: a scale of its own, derived
    // from that geometry's box, would differ from 1 where the scaling left a sphere too small to hit.
    void build_held(Accel& held, const Geometry& geometry, const BuildOptions& options) const;
    // update() of such a held structure, on geometry that update() has checked.
    UpdateReport update_held(Accel& held, const Geometry& geometry) const;
    // The layout of a structure this one is made of, which it traces as it is.
    [[nodiscard]] static ExportedLayout layout_of(const Accel& held) { return held.exported_layout(); }

  private:
    // World::update_vertices checks the positions it is given and takes the box of the triangles it flattens
    // from them, so it updates through update_within instead of going over every triangle again.
    friend class World;
    friend class CudaTracer;
    friend class GeometryQueries;  // walks a BVH's own arrays for the point queries
    friend class InstancedScene;   // traces a packet structure's objects through its single-ray structure

    // The arrays this structure lends as they are; none by default.
    [[nodiscard]] virtual ExportedLayout exported_layout() const { return {}; }
    // The structure's one-ray walk, for the triangle test it was built with; none (null) by default.
    [[nodiscard]] virtual SingleRayWalk single_ray_walk() const { return {}; }

    // The box of `geometry`'s primitives that can be hit; throws std::invalid_argument for a coordinate
    // outside the contract's domain.
    [[nodiscard]] static Box3f checked_bounds(const Geometry& geometry);
    // update() once `geometry` is known to have the built counts, coordinates inside the domain, and
    // `bounds` as the box of its primitives that can be hit.
    UpdateReport update_within(const Geometry& geometry, const Box3f& bounds);
    // Makes built_geometry and built_bounds for `geometry`, of box bounds_, at scale 2^scale_exponent_: the
    // caller's spans, or the scaled copy rewritten in place.
    void make_built_geometry(const Geometry& geometry);

    Box3f bounds_;
    std::size_t triangle_count_ = 0, sphere_count_ = 0;
    // The structure sees the scene scaled by 2^scale_exponent_ (0 for an ordinary scene, which it sees as
    // given); the scaled copy is kept here, for the structure keeps spans of its geometry.
    int scale_exponent_ = 0;
    std::vector<Triangle> scaled_triangles_;
    std::vector<Sphere> scaled_spheres_;
    Geometry built_geometry_;
    Box3f built_bounds_;
    // Counts the geometries this structure was given (builds and updates), so that what a reader keeps
    // derived from one (GeometryQueries' crossing grids) can tell when it no longer holds.
    std::uint64_t geometry_version_ = 0;
};

// intersect() and occluded() on `threads` threads (0: all, or those of the oneTBB arena the caller runs in),
// in tasks of 4096 consecutive rays from the batch's first (the last shorter): large enough to amortise a
// batch call, small enough to balance cores on uneven rays. Every task starts at a multiple of 4096 whatever
// the threads, so the packets of 64 a structure cuts from its call's start are the batch's own (a camera's
// 8x8 tiles stay whole). The same answers as one call; without oneTBB, one call.
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
