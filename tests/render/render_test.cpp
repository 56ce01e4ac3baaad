// The renderer on a tiny scene built in code, checked against values worked out by hand in double precision
// (the camera model of shared/bench/VIEWS.md written out again here, not PinholeCamera).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "accel/brute.hpp"
#include "lancer/render.hpp"
#include "lancer/vec3d.hpp"
#include "print_vec.hpp"

namespace lancer {
namespace {

// The eye at (0, 0, eye_z) looks down -z with up +y and a 90-degree field, so tan(fov / 2) = 1 and the frame
// is f = -z, x = +x, y = +y: pixel (i, j) looks along normalize(u, v, -1).
Camera camera_down_z(float eye_z, int width, int height) {
    Camera camera;
    camera.eye = {0.0f, 0.0f, eye_z};
    camera.look_at = {0.0f, 0.0f, 0.0f};
    camera.up = {0.0f, 1.0f, 0.0f};
    camera.vertical_fov_degrees = 90.0f;
    camera.width = width;
    camera.height = height;
    return camera;
}

Vec3d pixel_direction(const Camera& camera, int i, int j) {
    const double u = (2.0 * (i + 0.5) / camera.width - 1.0) * camera.width / camera.height;
    const double v = 1.0 - 2.0 * (j + 0.5) / camera.height;
    return normalize(Vec3d{u, v, -1.0});
}

Image render_with_brute(const Scene& scene, const Camera& camera, const RenderOptions& options,
                        RenderStats* stats = nullptr) {
    const SceneGeometry geometry(scene);
    BruteAccel accel;
    accel.build(geometry.view(), {});
    return render(scene, geometry, accel, camera, options, stats);
}

void expect_color_near(Vec3f actual, Vec3d expected, double tolerance = 1e-5) {
    EXPECT_NEAR(actual.x, expected.x, tolerance);
    EXPECT_NEAR(actual.y, expected.y, tolerance);
    EXPECT_NEAR(actual.z, expected.z, tolerance);
}

// ---------------------------------------------------------------------------------------------------------
// A tilted triangle on the left, a sphere on the right, a checkered floor below and empty sky above, seen
// by a 40x30 camera from z = 5 (40x30 so that rows and columns cannot be swapped unnoticed).
constexpr Vec3d kTriangleA{-6, -1, 0}, kTriangleB{-1, -1, 1}, kTriangleC{-3, 3, -1};
constexpr Vec3d kSphereCenter{3, 0, -1};
constexpr double kSphereRadius = 1.5;
constexpr double kFloorY = -2.0;
const Vec3f kTriangleColor{0.9f, 0.5f, 0.2f};
const Vec3f kSphereColor{0.3f, 0.8f, 0.4f};
const Vec3f kFloorColor{0.2f, 0.6f, 0.9f};
const Vec3f kBackground{0.1f, 0.2f, 0.3f};

Vec3f to_float(Vec3d a) {
    return {static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z)};
}

Scene tiny_scene() {
    Scene scene;
    TriangleMesh mesh;
    mesh.positions = {to_float(kTriangleA), to_float(kTriangleB), to_float(kTriangleC)};
    mesh.indices = {0, 1, 2};
    mesh.material = 0;
    scene.meshes.push_back(mesh);
    scene.spheres.push_back({to_float(kSphereCenter), static_cast<float>(kSphereRadius), 1});
    scene.planes.push_back({{0.0f, 1.0f, 0.0f}, static_cast<float>(kFloorY), 2, true});
    scene.materials.resize(3);
    scene.materials[0].color = kTriangleColor;
    scene.materials[1].color = kSphereColor;
    scene.materials[2].color = kFloorColor;
    scene.background = kBackground;
    return scene;
}

Camera tiny_camera() {
    return camera_down_z(5.0f, 40, 30);
}

RenderOptions with_mode(ShadingMode mode) {
    RenderOptions options;
    options.mode = mode;
    return options;
}

constexpr Vec3d kEye{0, 0, 5};

TEST(RenderFlat, TrianglePixelIsColourTimesAbsoluteCosine) {
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), with_mode(ShadingMode::Flat));
    const Vec3d normal = normalize(cross(kTriangleB - kTriangleA, kTriangleC - kTriangleA));
    const double cosine = std::fabs(dot(normal, pixel_direction(tiny_camera(), 10, 13)));
    ASSERT_GT(cosine, 0.1);
    ASSERT_LT(cosine, 0.99);  // tilted: a renderer that ignores the angle would fail
    expect_color_near(image.at(10, 13), cosine * Vec3d(kTriangleColor));
}

TEST(RenderFlat, SpherePixelUsesTheRadialNormal) {
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), with_mode(ShadingMode::Flat));
    const Vec3d direction = pixel_direction(tiny_camera(), 27, 14);
    // Nearer root of |eye + t d - c|^2 = r^2.
    const Vec3d offset = kEye - kSphereCenter;
    const double half_b = dot(offset, direction);
    const double t =
        -half_b - std::sqrt(half_b * half_b - (dot(offset, offset) - kSphereRadius * kSphereRadius));
    const Vec3d normal = (1.0 / kSphereRadius) * (kEye + t * direction - kSphereCenter);
    expect_color_near(image.at(27, 14), std::fabs(dot(normal, direction)) * Vec3d(kSphereColor));
}

TEST(RenderFlat, MissIsBackground) {
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), with_mode(ShadingMode::Flat));
    EXPECT_EQ(image.at(39, 0), kBackground);
    EXPECT_EQ(image.at(0, 0), kBackground);
}

TEST(RenderFlat, FloorAlternatesColourAndQuarterColour) {
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), with_mode(ShadingMode::Flat));
    // Pixels (20, 29) and (19, 29) land on either side of x = 0, at z ~ 2.93: cells (0, 2) and (-1, 2).
    for (const auto& [i, parity_even] : {std::pair{20, true}, std::pair{19, false}}) {
        SCOPED_TRACE(i);
        const Vec3d direction = pixel_direction(tiny_camera(), i, 29);
        const Vec3d point = kEye + ((kFloorY - kEye.y) / direction.y) * direction;
        ASSERT_EQ((static_cast<long>(std::floor(point.x)) + static_cast<long>(std::floor(point.z))) % 2 == 0,
                  parity_even);
        const double checker = parity_even ? 1.0 : 0.25;
        expect_color_near(image.at(i, 29), checker * std::fabs(direction.y) * Vec3d(kFloorColor));
    }
}

TEST(RenderNormal, MissIsBackground) {
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), with_mode(ShadingMode::Normal));
    EXPECT_EQ(image.at(39, 0), kBackground);
}

TEST(RenderNormal, FloorMapsUpToGreen) {
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), with_mode(ShadingMode::Normal));
    EXPECT_EQ(image.at(20, 29), Vec3f(0.5f, 1.0f, 0.5f));
}

// One triangle in the plane z = 0 spanning the view of a 9x9 camera at z = 4.
Scene facing_triangle_scene(bool counter_clockwise) {
    Scene scene;
    TriangleMesh mesh;
    mesh.positions = {{-10.0f, -10.0f, 0.0f}, {10.0f, -10.0f, 0.0f}, {0.0f, 10.0f, 0.0f}};
    mesh.indices =
        counter_clockwise ? std::vector<std::uint32_t>{0, 1, 2} : std::vector<std::uint32_t>{0, 2, 1};
    scene.meshes.push_back(mesh);
    scene.materials.resize(1);
    return scene;
}

TEST(RenderNormal, AxisAlignedTriangleFacingTheCameraIsBlueish) {
    const Image image = render_with_brute(facing_triangle_scene(true), camera_down_z(4.0f, 9, 9),
                                          with_mode(ShadingMode::Normal));
    EXPECT_EQ(image.at(4, 4), Vec3f(0.5f, 0.5f, 1.0f));
    EXPECT_EQ(image.at(1, 7), Vec3f(0.5f, 0.5f, 1.0f));
}

TEST(RenderNormal, BackSideIsFlippedTowardsTheRay) {
    const Image image = render_with_brute(facing_triangle_scene(false), camera_down_z(4.0f, 9, 9),
                                          with_mode(ShadingMode::Normal));
    EXPECT_EQ(image.at(4, 4), Vec3f(0.5f, 0.5f, 1.0f));
}

TEST(RenderNormal, VertexNormalsAreInterpolatedWithTheBarycentrics) {
    Scene scene = facing_triangle_scene(true);
    const Vec3d n0 = normalize(Vec3d{0, 0, 1}), n1 = normalize(Vec3d{1, 0, 1}),
                n2 = normalize(Vec3d{0, 1, 2});
    scene.meshes[0].normals = {to_float(n0), to_float(n1), to_float(n2)};
    const Camera camera = camera_down_z(4.0f, 9, 9);
    const Image image = render_with_brute(scene, camera, with_mode(ShadingMode::Normal));

    const int i = 5, j = 3;
    const Vec3d direction = pixel_direction(camera, i, j);
    const Vec3d point = Vec3d{0, 0, 4} + (-4.0 / direction.z) * direction;
    // point = (1 - u - v) (-10, -10) + u (10, -10) + v (0, 10), solved for v then u.
    const double v = (point.y + 10.0) / 20.0;
    const double u = (point.x + 10.0 - 10.0 * v) / 20.0;
    const Vec3d normal = normalize((1.0 - u - v) * n0 + (u * n1 + v * n2));
    expect_color_near(image.at(i, j), 0.5 * normal + Vec3d{0.5, 0.5, 0.5});
}

TEST(RenderFlat, SmoothMeshStaysFaceted) {
    Scene scene = facing_triangle_scene(true);
    scene.meshes[0].normals = {to_float(normalize(Vec3d{1, 0, 1})), to_float(normalize(Vec3d{1, 0, 1})),
                               to_float(normalize(Vec3d{1, 0, 1}))};
    const Camera camera = camera_down_z(4.0f, 9, 9);
    const Image image = render_with_brute(scene, camera, with_mode(ShadingMode::Flat));
    // The facet's normal is +z whatever the vertex normals say.
    const double cosine = std::fabs(pixel_direction(camera, 5, 3).z);
    expect_color_near(image.at(5, 3), cosine * Vec3d(scene.materials[0].color));
}

TEST(RenderDepth, NearestHitWhiteFarthestBlackMissBlack) {
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), with_mode(ShadingMode::Depth));
    EXPECT_EQ(image.at(39, 0), Vec3f(0.0f));
    float brightest = 0.0f;
    for (const Vec3f& pixel : image.pixels) {
        EXPECT_EQ(pixel.x, pixel.y);
        EXPECT_EQ(pixel.x, pixel.z);
        EXPECT_GE(pixel.x, 0.0f);
        EXPECT_LE(pixel.x, 1.0f);
        brightest = std::max(brightest, pixel.x);
    }
    EXPECT_EQ(brightest, 1.0f);
}

// A 3x3 view straight onto the plane z = 0 from z = 5: t = 5 sqrt(1 + u^2 + v^2) with u, v in {-2/3, 0, 2/3}.
TEST(RenderDepth, NormalisedOverTheImageHits) {
    Scene scene;
    scene.planes.push_back({{0.0f, 0.0f, 1.0f}, 0.0f, 0, false});
    scene.materials.resize(1);
    const Image image = render_with_brute(scene, camera_down_z(5.0f, 3, 3), with_mode(ShadingMode::Depth));
    const double nearest = 5.0, edge = 5.0 * std::sqrt(1.0 + 4.0 / 9.0),
                 corner = 5.0 * std::sqrt(1.0 + 8.0 / 9.0);
    EXPECT_EQ(image.at(1, 1), Vec3f(1.0f));
    EXPECT_NEAR(image.at(0, 0).x, 0.0, 1e-5);
    EXPECT_NEAR(image.at(2, 2).x, 0.0, 1e-5);
    const double edge_value = 1.0 - (edge - nearest) / (corner - nearest);
    EXPECT_NEAR(image.at(1, 0).x, edge_value, 1e-5);
    EXPECT_NEAR(image.at(0, 1).x, edge_value, 1e-5);
    EXPECT_NEAR(image.at(2, 1).x, edge_value, 1e-5);
}

TEST(RenderDepth, HitsAllAtOneDistanceAreWhite) {
    Scene scene;
    scene.planes.push_back({{0.0f, 0.0f, 1.0f}, 0.0f, 0, false});
    scene.materials.resize(1);
    const Image image = render_with_brute(scene, camera_down_z(5.0f, 1, 1), with_mode(ShadingMode::Depth));
    EXPECT_EQ(image.at(0, 0), Vec3f(1.0f));
}

TEST(Render, SameBitsWhateverThreadsAndTiles) {
    const Scene scene = tiny_scene();
    for (ShadingMode mode : {ShadingMode::Flat, ShadingMode::Normal, ShadingMode::Depth}) {
        RenderOptions reference_options = with_mode(mode);
        reference_options.threads = 1;
        reference_options.tile_size = 16;
        const Image reference = render_with_brute(scene, tiny_camera(), reference_options);
        for (int threads : {1, 2, 3}) {
            for (int tile_size : {1, 7, 16, 64}) {
                SCOPED_TRACE(testing::Message() << "mode " << static_cast<int>(mode) << ", threads "
                                                << threads << ", tile " << tile_size);
                RenderOptions options = with_mode(mode);
                options.threads = threads;
                options.tile_size = tile_size;
                const Image image = render_with_brute(scene, tiny_camera(), options);
                ASSERT_EQ(image.pixels.size(), reference.pixels.size());
                EXPECT_EQ(std::memcmp(image.pixels.data(), reference.pixels.data(),
                                      image.pixels.size() * sizeof(Vec3f)),
                          0);
            }
        }
    }
}

// The primary modes trace 8x8 packets (Accel::intersect_packet): the packet structures' own kernels, over
// tiles that packets overhang (7) and an image that is not a whole number of packets (40x30), give the
// brute-force image bit for bit.
TEST(Render, PacketStructuresGiveTheBruteForceImage) {
    const Scene scene = tiny_scene();
    const SceneGeometry geometry(scene);
    for (ShadingMode mode : {ShadingMode::Flat, ShadingMode::Normal, ShadingMode::Depth}) {
        const Image reference = render_with_brute(scene, tiny_camera(), with_mode(mode));
        for (const char* name : {"bvh8_packet", "bvh_packet", "bvh"}) {
            const std::unique_ptr<Accel> accel = make_accel(name);
            accel->build(geometry.view(), {});
            for (int tile_size : {7, 16}) {
                SCOPED_TRACE(testing::Message()
                             << "mode " << static_cast<int>(mode) << ", " << name << ", tile " << tile_size);
                RenderOptions options = with_mode(mode);
                options.tile_size = tile_size;
                const Image image = render(scene, geometry, *accel, tiny_camera(), options);
                ASSERT_EQ(image.pixels.size(), reference.pixels.size());
                EXPECT_EQ(std::memcmp(image.pixels.data(), reference.pixels.data(),
                                      image.pixels.size() * sizeof(Vec3f)),
                          0);
            }
        }
    }
}

// Distributed rendering's contract (docs/distributed.md): parts that hold every tile once, in any split and
// order, assemble into render()'s image bit for bit, in every mode (Whitted with its secondary rays; Depth
// and Heatmap, whose image is made from the whole frame), with the same ray counts.
TEST(RenderParts, AssembleIntoTheSingleProcessImage) {
    Scene scene = tiny_scene();
    scene.lights.push_back({{3.0f, 4.0f, 6.0f}, Vec3f(1.0f)});
    scene.materials[1].ks = 0.5f;
    const SceneGeometry geometry(scene);
    const std::unique_ptr<Accel> accel = make_accel("bvh");
    accel->build(geometry.view(), {});
    for (ShadingMode mode :
         {ShadingMode::Whitted, ShadingMode::Flat, ShadingMode::Depth, ShadingMode::Heatmap}) {
        RenderOptions options = with_mode(mode);
        options.tile_size = 7;
        options.samples_per_pixel = mode == ShadingMode::Whitted ? 2 : 1;
        RenderStats reference_stats;
        const Image reference = render(scene, geometry, *accel, tiny_camera(), options, &reference_stats);
        const std::size_t tiles = frame_tile_count(tiny_camera(), options);
        ASSERT_EQ(tiles, 6u * 5u);
        // Three parts: the odd tiles backwards in batches of 4, the even tiles below 12, the rest one by one.
        std::vector<std::vector<std::size_t>> batches[3];
        std::vector<std::size_t> odd;
        for (std::size_t tile = tiles; tile-- > 0;)
            if (tile % 2 == 1) odd.push_back(tile);
        for (std::size_t k = 0; k < odd.size(); k += 4)
            batches[0].emplace_back(odd.begin() + static_cast<std::ptrdiff_t>(k),
                                    odd.begin() + static_cast<std::ptrdiff_t>(std::min(k + 4, odd.size())));
        batches[1].emplace_back();
        for (std::size_t tile = 0; tile < tiles; tile += 2) {
            if (tile < 12)
                batches[1][0].push_back(tile);
            else
                batches[2].push_back({tile});
        }
        std::vector<FramePart> parts;
        for (auto& part_batches : batches) {
            std::size_t next = 0;
            parts.push_back(render_part(scene, geometry, *accel, tiny_camera(), options, [&] {
                return next < part_batches.size() ? part_batches[next++] : std::vector<std::size_t>{};
            }));
        }
        SCOPED_TRACE(testing::Message() << "mode " << static_cast<int>(mode));
        RenderStats stats;
        const Image image = assemble_frame(tiny_camera(), options, parts, &stats);
        ASSERT_EQ(image.pixels.size(), reference.pixels.size());
        EXPECT_EQ(
            std::memcmp(image.pixels.data(), reference.pixels.data(), image.pixels.size() * sizeof(Vec3f)),
            0);
        EXPECT_EQ(stats.total_rays(), reference_stats.total_rays());
        EXPECT_EQ(stats.counters.nodes_visited, reference_stats.counters.nodes_visited);
        if (mode == ShadingMode::Whitted) {
            EXPECT_GT(stats.shadow_rays, 0u);
        }
    }
}

TEST(RenderParts, AssemblyRefusesPartsThatDoNotTileTheFrame) {
    const Scene scene = tiny_scene();
    const SceneGeometry geometry(scene);
    const std::unique_ptr<Accel> accel = make_accel("bvh");
    accel->build(geometry.view(), {});
    RenderOptions options = with_mode(ShadingMode::Flat);
    options.tile_size = 16;
    auto part_of = [&](std::vector<std::size_t> tiles) {
        bool given = false;
        return render_part(scene, geometry, *accel, tiny_camera(), options, [&] {
            std::vector<std::size_t> batch;
            if (!given) batch = tiles, given = true;
            return batch;
        });
    };
    ASSERT_EQ(frame_tile_count(tiny_camera(), options), 6u);  // 40x30 in tiles of 16: 3 x 2
    const std::vector<FramePart> missing = {part_of({0, 1, 2}), part_of({3, 4})};
    EXPECT_THROW(static_cast<void>(assemble_frame(tiny_camera(), options, missing)), std::invalid_argument);
    const std::vector<FramePart> repeated = {part_of({0, 1, 2}), part_of({2, 3, 4, 5})};
    EXPECT_THROW(static_cast<void>(assemble_frame(tiny_camera(), options, repeated)), std::invalid_argument);
    const std::vector<FramePart> whole = {part_of({5, 3, 1}), part_of({0, 2, 4})};
    RenderStats whole_stats;
    const Image assembled = assemble_frame(tiny_camera(), options, whole, &whole_stats);
    const Image reference = render(scene, geometry, *accel, tiny_camera(), options);
    ASSERT_EQ(assembled.pixels.size(), reference.pixels.size());
    EXPECT_EQ(std::memcmp(assembled.pixels.data(), reference.pixels.data(),
                          assembled.pixels.size() * sizeof(Vec3f)),
              0);
    EXPECT_EQ(whole_stats.primary_rays, 40u * 30u);
    std::vector<FramePart> cut_short = whole, padded = whole;
    cut_short[1].pixels.pop_back();
    EXPECT_THROW(static_cast<void>(assemble_frame(tiny_camera(), options, cut_short)), std::invalid_argument);
    padded[1].pixels.push_back(Vec3f(0.0f));
    EXPECT_THROW(static_cast<void>(assemble_frame(tiny_camera(), options, padded)), std::invalid_argument);
    EXPECT_THROW(static_cast<void>(part_of({6})), std::invalid_argument);
}

TEST(Render, StatsCountOneRayPerPixel) {
    RenderStats stats;
    const Image image = render_with_brute(tiny_scene(), tiny_camera(), {}, &stats);
    EXPECT_EQ(image.width, 40);
    EXPECT_EQ(image.height, 30);
    EXPECT_EQ(stats.primary_rays, 40u * 30u);
    // Whitted mode, but the tiny scene has no light, no mirror and no glass: no secondary ray.
    EXPECT_EQ(stats.shadow_rays, 0u);
    EXPECT_EQ(stats.reflection_rays, 0u);
    EXPECT_EQ(stats.refraction_rays, 0u);
}

// A floor that mirrors and transmits, lit from above, under the 40x30 view: rows 15 to 29 look down onto it
// (v < 0), rows 0 to 14 look up into empty sky. Each floor hit faces the light, so casts one shadow ray, and
// spawns one mirror and one refracted ray, which leave upwards and downwards into nothing.
TEST(Render, StatsCountRaysOfEachKind) {
    Scene scene;
    scene.planes.push_back({{0.0f, 1.0f, 0.0f}, static_cast<float>(kFloorY), 0, false});
    scene.materials.resize(1);
    scene.materials[0].ks = 0.5f;
    scene.materials[0].kt = 0.3f;
    scene.materials[0].ior = 1.5f;
    scene.lights.push_back({{0.0f, 10.0f, 0.0f}, Vec3f(1.0f)});
    RenderStats stats;
    (void)render_with_brute(scene, tiny_camera(), with_mode(ShadingMode::Whitted), &stats);
    const std::uint64_t floor_hits = 15u * 40u;
    EXPECT_EQ(stats.primary_rays, 40u * 30u);
    EXPECT_EQ(stats.shadow_rays, floor_hits);
    EXPECT_EQ(stats.reflection_rays, floor_hits);
    EXPECT_EQ(stats.refraction_rays, floor_hits);
}

TEST(Render, ProgressLineCountsTiles) {
    RenderOptions options;
    options.progress = true;
    testing::internal::CaptureStderr();
    (void)render_with_brute(tiny_scene(), tiny_camera(), options);
    const std::string output = testing::internal::GetCapturedStderr();
    EXPECT_NE(output.find("render 100% (6/6 tiles)"), std::string::npos) << output;  // 3 x 2 tiles of 16
    EXPECT_EQ(output.back(), '\n');
}

TEST(Render, SilentWithoutProgress) {
    testing::internal::CaptureStderr();
    (void)render_with_brute(tiny_scene(), tiny_camera(), {});
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

TEST(Render, RejectsBadOptions) {
    RenderOptions zero_tile;
    zero_tile.tile_size = 0;
    EXPECT_THROW((void)render_with_brute(tiny_scene(), tiny_camera(), zero_tile), std::invalid_argument);
    RenderOptions negative_threads;
    negative_threads.threads = -1;
    EXPECT_THROW((void)render_with_brute(tiny_scene(), tiny_camera(), negative_threads),
                 std::invalid_argument);
    EXPECT_THROW((void)render_with_brute(tiny_scene(), camera_down_z(5.0f, 0, 10), {}),
                 std::invalid_argument);
}

}  // namespace
}  // namespace lancer
