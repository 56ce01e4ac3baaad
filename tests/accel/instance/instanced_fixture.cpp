#include "instanced_fixture.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "lancer/generate.hpp"

namespace lancer::testing {

double length(const Vec3d& v) {
    return std::sqrt(dot(v, v));
}

Fixture random_fixture(std::uint32_t seed, int instances) {
    Fixture fixture;
    fixture.object_triangles.push_back(make_icosphere(2).triangles());
    fixture.object_triangles.push_back(make_torus_knot(48, 6).triangles());
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), scale(0.3f, 2.0f), angle(0.0f, 6.2831853f);
    for (int i = 0; i < instances; ++i) {
        const Vec3f axis(unit(rng), unit(rng), unit(rng) + 1.5f);
        fixture.transforms.push_back(
            Transform::translation({6.0f * unit(rng), 6.0f * unit(rng), 6.0f * unit(rng)}) *
            Transform::rotation(axis, angle(rng)) * Transform::scaling({scale(rng), scale(rng), scale(rng)}));
        fixture.objects.push_back(static_cast<std::uint32_t>(i % 2));
    }
    return fixture;
}

FlatScene flatten(const Fixture& fixture) {
    FlatScene flat;
    for (std::size_t i = 0; i < fixture.transforms.size(); ++i) {
        const Affine affine(fixture.transforms[i]);
        flat.transforms.push_back(affine);
        const auto& triangles = fixture.object_triangles[fixture.objects[i]];
        double object_size = 0.0;
        for (const Triangle& t : triangles)
            object_size =
                std::max({object_size, length(Vec3d(t.v0)), length(Vec3d(t.v1)), length(Vec3d(t.v2))});
        flat.object_sizes.push_back(object_size);
        for (std::size_t prim = 0; prim < triangles.size(); ++prim) {
            const Triangle& t = triangles[prim];
            flat.triangles.push_back({static_cast<std::int32_t>(i), static_cast<std::int32_t>(prim),
                                      affine.point(t.v0), affine.point(t.v1), affine.point(t.v2)});
        }
    }
    return flat;
}

TriangleMesh mesh_of(const std::vector<Triangle>& triangles) {
    TriangleMesh mesh;
    for (const Triangle& t : triangles) {
        for (const Vec3f& p : {t.v0, t.v1, t.v2}) {
            mesh.indices.push_back(static_cast<std::uint32_t>(mesh.positions.size()));
            mesh.positions.push_back(p);
        }
    }
    return mesh;
}

InstancedScene make_scene(const Fixture& fixture, std::string_view accel, TriangleTest test,
                          const std::vector<std::uint32_t>& skipped) {
    InstancedScene scene;
    for (const auto& triangles : fixture.object_triangles)
        scene.add_object(mesh_of(triangles), accel, build_options(test));
    for (std::uint32_t i = 0; i < fixture.transforms.size(); ++i) {
        if (std::ranges::find(skipped, i) != skipped.end())
            scene.skip_instance_id();
        else
            scene.add_instance(fixture.objects[i], fixture.transforms[i]);
    }
    scene.commit();
    return scene;
}

RaySet inside_and_grazing_rays(const Fixture& fixture, const FlatScene& flat, std::size_t count,
                               std::uint32_t seed) {
    RaySet set{"inside and grazing", {}};
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    for (std::size_t i = 0; i < count; ++i) {
        if (i % 2 == 0) {
            const Transform& t = fixture.transforms[i / 2 % fixture.transforms.size()];
            const Vec3f centre(t.m[0][3], t.m[1][3], t.m[2][3]);
            set.rays.push_back({centre, {unit(rng), unit(rng), unit(rng)}, 0.0f, kInfinity});
            continue;
        }
        const FlatScene::Placed& placed = flat.triangles[rng() % flat.triangles.size()];
        const Vec3d e1 = placed.v1 - placed.v0, e2 = placed.v2 - placed.v0;
        const Vec3d n = normalize(cross(e1, e2));
        const Vec3d target = placed.v0 + 0.3 * e1 + 0.3 * e2;
        const Vec3d along = normalize(e1);
        const double tilt = 1e-3 * unit(rng);
        const Vec3d direction = along + tilt * n;
        const Vec3d origin = target - 2.0 * direction;
        set.rays.push_back(
            {{static_cast<float>(origin.x), static_cast<float>(origin.y), static_cast<float>(origin.z)},
             {static_cast<float>(direction.x), static_cast<float>(direction.y),
              static_cast<float>(direction.z)},
             0.0f,
             kInfinity});
    }
    return set;
}

std::string case_name(const ::testing::TestParamInfo<Case>& param_info) {
    return std::string(param_info.param.accel) +
           (param_info.param.test == TriangleTest::Watertight ? "_watertight" : "_moller");
}

}  // namespace lancer::testing
