// What the packet structures share: each traces the build of a single-ray structure, untouched, so it holds
// that structure with the geometry and triangle test it was built for, and reports the single-ray
// structure's stats and memory. A packet structure writes only its batch methods.
#pragma once

#include "lancer/accel.hpp"

namespace lancer {

template <class SingleRay>
class PacketAccel : public Accel {
  public:
    // The build of the single-ray structure.
    [[nodiscard]] AccelStats stats() const override { return single_ray_.stats(); }
    [[nodiscard]] std::size_t memory_bytes() const override { return single_ray_.memory_bytes(); }
    [[nodiscard]] UpdateMethod update_method() const override { return single_ray_.update_method(); }

  protected:
    void build_structure(const Geometry& geometry, const BuildOptions& options) override {
        build_held(single_ray_, geometry, options);
        geometry_ = geometry;
        triangle_test_ = options.triangle_test;
    }
    UpdateReport update_structure(const Geometry& geometry) override {
        geometry_ = geometry;
        return update_held(single_ray_, geometry);
    }
    // The single-ray structure's arrays, which the packets trace untouched, and the structure itself.
    [[nodiscard]] ExportedLayout exported_layout() const override {
        ExportedLayout layout = layout_of(single_ray_);
        layout.single_ray = &single_ray_;
        return layout;
    }

    SingleRay single_ray_;
    Geometry geometry_;
    TriangleTest triangle_test_ = TriangleTest::MollerTrumbore;
};

}  // namespace lancer
