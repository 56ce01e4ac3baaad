#include "accel/bvh/bvh8_packet.hpp"

#include "accel/bvh/bvh8_packet_kernel.hpp"
#include "lancer/isa.hpp"

namespace lancer {
namespace {

// The kernels of `isa`, or none where a build without AVX2 has none (bvh8 then traces every ray).
const Bvh8PacketKernels* kernels_for(SimdIsa isa) {
    if (isa == SimdIsa::Auto && available_isas().empty()) return nullptr;
    switch (resolve_isa(isa)) {
#if LANCER_HAS_AVX512_KERNELS
        case SimdIsa::Avx512:
            return &avx512::bvh8_packet_kernels();
#endif
#if defined(__AVX2__)
        case SimdIsa::Avx2:
            return &avx2::bvh8_packet_kernels();
#endif
        default:
            return nullptr;
    }
}

}  // namespace

// The mean diagonal of the tree's leaf boxes: the scale below which a packet's rays share leaves.
float mean_leaf_diagonal(const Bvh8Accel& bvh) {
    double sum = 0.0;
    std::size_t leaves = 0;
    for (const WideBvhNode<8>& node : bvh.nodes()) {
        for (int slot = 0; slot < 8; ++slot) {
            if (node.is_empty(slot) || node.prim_count[slot] == 0) continue;
            sum += static_cast<double>(length(node.child_bounds(slot).extent()));
            ++leaves;
        }
    }
    return leaves == 0 ? 0.0f : static_cast<float>(sum / static_cast<double>(leaves));
}

void Bvh8PacketAccel::build_structure(const Geometry& geometry, const BuildOptions& options) {
    kernels_ = kernels_for(options.isa);
    // The ray streams' block boxes (bvh.leaf_boxes) pay while the leaves stay in the caches.
    BuildOptions tree_options = options;
    LeafBoxes& leaf_boxes = tree_options.group<BvhOptions>().leaf_boxes;
    if (leaf_boxes == LeafBoxes::Auto)
        leaf_boxes = geometry.size() <= kLeafBoxesUpTo ? LeafBoxes::On : LeafBoxes::Off;
    PacketAccel::build_structure(geometry, tree_options);
    leaf_diagonal_ = mean_leaf_diagonal(single_ray_);
    const InterleavedStreams interleaved = options.group<BvhOptions>().interleaved_streams;
    streams_in_flight_ = interleaved == InterleavedStreams::On || (interleaved == InterleavedStreams::Auto &&
                                                                   geometry.size() >= kInterleavedStreamsFrom)
                             ? kStreamsInFlight
                             : 1;
}

UpdateReport Bvh8PacketAccel::update_structure(const Geometry& geometry) {
    const UpdateReport report = PacketAccel::update_structure(geometry);
    leaf_diagonal_ = mean_leaf_diagonal(single_ray_);
    return report;
}

Bvh8PacketTarget Bvh8PacketAccel::target() const {
    return {single_ray_, geometry_, triangle_test_, leaf_diagonal_, streams_in_flight_};
}

int Bvh8PacketAccel::lane_count() const {
    return kernels_ != nullptr ? kernels_->lane_count : 1;
}

void Bvh8PacketAccel::intersect_batch(std::span<const Ray> rays, std::span<Hit> hits,
                                      TraversalCounters* counters) const {
    if (kernels_ == nullptr) return single_ray_.intersect(rays, hits, counters);
    kernels_->intersect(target(), rays, hits, counters);
}

void Bvh8PacketAccel::intersect_packet_rays(const RayPacket& rays, HitPacket& hits,
                                            TraversalCounters* counters) const {
    if (kernels_ == nullptr) return Accel::intersect_packet_rays(rays, hits, counters);
    kernels_->intersect_packet(target(), rays, hits, counters);
}

void Bvh8PacketAccel::occluded_batch(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                                     TraversalCounters* counters) const {
    if (kernels_ == nullptr) return single_ray_.occluded(rays, occluded, counters);
    kernels_->occluded(target(), rays, occluded, counters);
}

}  // namespace lancer
