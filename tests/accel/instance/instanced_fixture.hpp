// The instance tests' shared fixture (instanced_contract_test.cpp, instanced_scene_test.cpp,
// object_structures_test.cpp): objects placed by random transforms, the same scene flattened in double
// precision, the InstancedScene built over it, and rays that start inside instances or graze their triangles.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lancer/instances.hpp"
#include "lancer/vec3d.hpp"
#include "support/ray_sets.hpp"

namespace lancer::testing {

// An instance's transform in double, so that the flattened scene's vertices carry no rounding of their own.
struct Affine {
    double a[3][3];
    double b[3];

    explicit Affine(const Transform& t) {
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c)
                a[r][c] = t.m[r][c];
            b[r] = t.m[r][3];
        }
    }
    [[nodiscard]] Vec3d point(const Vec3f& p) const { return apply(Vec3d(p), true); }
    [[nodiscard]] Vec3d apply(const Vec3d& p, bool translate) const {
        const double x[3] = {p.x, p.y, p.z};
        double out[3];
        for (int r = 0; r < 3; ++r)
            out[r] = a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2] + (translate ? b[r] : 0.0);
        return {out[0], out[1], out[2]};
    }
};

// A vector's length in double (lancer/vec3d.hpp has none).
double length(const Vec3d& v);

// The scene flattened: each instance's triangles mapped to the world in double.
struct FlatScene {
    struct Placed {
        std::int32_t instance;
        std::int32_t prim;
        Vec3d v0, v1, v2;
    };
    std::vector<Placed> triangles;
    std::vector<Affine> transforms;    // by instance
    std::vector<double> object_sizes;  // by instance: the object's largest vertex norm
};

// The objects' triangles and the instances placing them, from which make_scene and flatten build.
struct Fixture {
    std::vector<std::vector<Triangle>> object_triangles;
    std::vector<Transform> transforms;
    std::vector<std::uint32_t> objects;  // of each instance
};

// A few objects placed by random rotations, non-uniform scales and translations, no two alike, overlapping.
Fixture random_fixture(std::uint32_t seed, int instances);

// The fixture's instances mapped to the world in double: the scene every hit is held to.
FlatScene flatten(const Fixture& fixture);

// The triangles as a mesh of their own (no vertex shared), as InstancedScene::add_object takes them.
TriangleMesh mesh_of(const std::vector<Triangle>& triangles);

// The fixture's instances under ids 0, 1, ..., the ids in `skipped` passed over (skip_instance_id), their
// instances left out.
InstancedScene make_scene(const Fixture& fixture, std::string_view accel, TriangleTest test,
                          const std::vector<std::uint32_t>& skipped = {});

// Rays that start inside instances (at their centres), and rays grazing triangles: from a point of a
// triangle's plane near it, along the plane with a small normal component.
RaySet inside_and_grazing_rays(const Fixture& fixture, const FlatScene& flat, std::size_t count,
                               std::uint32_t seed);

// The parameter of the tests run over object structures and triangle tests.
struct Case {
    std::string_view accel;
    TriangleTest test;
};

// A Case's name in the test list: the structure and the triangle test (bvh8_watertight, bvh8_moller).
std::string case_name(const ::testing::TestParamInfo<Case>& param_info);

}  // namespace lancer::testing
