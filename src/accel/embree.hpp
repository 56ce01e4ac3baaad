// Intel Embree behind lancer's interface, so that it is measured in the same process, on the same rays and
// threads as lancer's own structures (docs/results.md), called the way its manual asks for speed
// (docs/results.md, "Embree at its best"): one structure per call, `embree` (rtcIntersect1, rtcOccluded1),
// `embree8` and `embree16` (packets of 8 and 16 consecutive rays: 4x2 and 4x4 pixels in a coherent batch,
// which gets the COHERENT flag), `embree_stream` (rtcIntersect1M, rtcOccluded1M on streams of consecutive
// rays: a coherent batch with the COHERENT flag, the call Embree's overview recommends for coherent rays; the
// others without it, where the overview expects streams to beat single rays too). Compiled in when Debian's
// Embree 3 is found (LANCER_EMBREE). Embree uses its own triangle test (watertight when --watertight sets its
// robust mode) and its own traversal: it is a peer to compare with, not one of our kernels, so it is checked
// against brute force by tests/accel/embree_test.cpp rather than held to the bit-exact oracle test.
#pragma once

#include <atomic>

#include <embree3/rtcore.h>

#include <string_view>
#include <vector>

#include "accel/options.hpp"
#include "lancer/accel.hpp"

namespace lancer {

// The options of the `embree` structures: Embree's build quality, HIGH (with spatial splits, its best trace
// speed), MEDIUM (the faster build), or REFIT (a LOW-quality dynamic scene whose BVH Accel::update refits).
enum class EmbreeQuality { High, Medium, Refit };
struct EmbreeOptions {
    static constexpr std::string_view kGroup = "embree";
    EmbreeQuality quality = EmbreeQuality::High;
};

// The ids of lancer's triangles and spheres in Embree's scene, one geometry each: Embree numbers primitives
// per geometry, and lancer's hits number the spheres after the triangles.
inline constexpr unsigned int kEmbreeTriangleGeometry = 0;
inline constexpr unsigned int kEmbreeSphereGeometry = 1;

// The Embree call a structure traces with: one ray at a time, packets of 8 or 16 rays, or streams.
enum class EmbreeCall { Single, Packet8, Packet16, Stream };

class EmbreeAccel final : public Accel {
  public:
    // The `--set` keys of this structure's option group (accel/options.hpp).
    [[nodiscard]] static std::vector<BuildOptionRow> option_rows();
    explicit EmbreeAccel(EmbreeCall call);
    ~EmbreeAccel() override;
    EmbreeAccel(const EmbreeAccel&) = delete;
    EmbreeAccel& operator=(const EmbreeAccel&) = delete;

    [[nodiscard]] std::string_view name() const override;
    [[nodiscard]] AccelStats stats() const override;
    // What Embree's device holds, by its memory monitor (rtcSetDeviceMemoryMonitorFunction): the BVH, its
    // copies of the vertices and indices, and its other internal arrays. Unlike lancer's structures this
    // includes a copy of the geometry, which Embree traces from.
    [[nodiscard]] std::size_t memory_bytes() const override;
    [[nodiscard]] UpdateMethod update_method() const override {
        return quality_ == EmbreeQuality::Refit ? UpdateMethod::Refit : UpdateMethod::Rebuild;
    }

  private:
    void build_structure(const Geometry& geometry, const BuildOptions& options) override;
    UpdateReport update_structure(const Geometry& geometry) override;
    void intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                         TraversalCounters* counters) const override;
    void occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                        TraversalCounters* counters) const override;
    void intersect_coherent_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                  TraversalCounters* counters) const override;
    void intersect_packet_rays(const RayPacket& rays, HitPacket& hits,
                               TraversalCounters* counters) const override;
    void intersect_with_flags(std::span<const Ray> rays, std::span<Hit> hits,
                              RTCIntersectContextFlags flags) const;
    void release_scene();

    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    Box3f
        scene_box_;  // grown by the geometric tolerance: where a ray with tnear < 0 starts (embree_rays.cpp)
    float scene_scale_ =
        1.0f;  // the power of two Embree's copy of the scene is scaled by (embree.cpp, scene_scale)
    unsigned int triangle_count_ = 0;
    std::size_t primitive_count_ = 0;
    std::size_t buffer_bytes_ = 0;
    std::atomic<std::int64_t> device_bytes_{0};  // what the device holds (monitor_memory)
    double build_ms_ = 0.0;
    EmbreeCall call_ = EmbreeCall::Single;
    EmbreeQuality quality_ = EmbreeQuality::High;
    TriangleTest triangle_test_ = TriangleTest::MollerTrumbore;
};

}  // namespace lancer
