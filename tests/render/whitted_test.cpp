// The Whitted renderer on scenes built in code: properties that a wrong ray tree, a wrong refraction, a
// leaking shadow ray or a bad secondary-ray offset would break.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <string>

#include "lancer/accel.hpp"
#include "lancer/camera.hpp"
#include "lancer/generate.hpp"
#include "lancer/render.hpp"
#include "print_vec.hpp"

namespace lancer {
namespace {

Camera look(Vec3f eye, Vec3f at, Vec3f up, float fov_degrees, int width, int height) {
    Camera camera;
    camera.eye = eye;
    camera.look_at = at;
    camera.up = up;
    camera.vertical_fov_degrees = fov_degrees;
    camera.width = width;
    camera.height = height;
    return camera;
}

Material diffuse(Vec3f color) {
    Material material;
    material.color = color;
    material.kd = 1.0f;
    return material;
}

Material mirror(float ks) {
    Material material;
    material.kd = 0.0f;
    material.ks = ks;
    return material;
}

Material glass(float ior) {
    Material material;
    material.kd = 0.0f;
    material.kt = 1.0f;
    material.ior = ior;
    material.two_sided = true;
    return material;
}

std::uint32_t add_material(Scene& scene, const Material& material) {
    scene.materials.push_back(material);
    return static_cast<std::uint32_t>(scene.materials.size() - 1);
}

// The quad a b c d as two triangles (a b c, a c d): counter-clockwise seen from its front.
void add_quad(Scene& scene, Vec3f a, Vec3f b, Vec3f c, Vec3f d, std::uint32_t material) {
    TriangleMesh mesh;
    mesh.name = "quad";
    mesh.positions = {a, b, c, d};
    mesh.indices = {0, 1, 2, 0, 2, 3};
    mesh.material = material;
    scene.meshes.push_back(mesh);
}

RenderOptions whitted(int samples_per_pixel = 1) {
    RenderOptions options;
    options.mode = ShadingMode::Whitted;
    options.samples_per_pixel = samples_per_pixel;
    options.min_weight = 0.0f;
    return options;
}

Image render_with(std::string_view accel_name, const Scene& scene, const Camera& camera,
                  const RenderOptions& options, RenderStats* stats = nullptr) {
    const SceneGeometry geometry(scene);
    const std::unique_ptr<Accel> accel = make_accel(accel_name);
    accel->build(geometry.view(), {});
    return render(scene, geometry, *accel, camera, options, stats);
}

Image render_brute(const Scene& scene, const Camera& camera, const RenderOptions& options,
                   RenderStats* stats = nullptr) {
    return render_with("brute", scene, camera, options, stats);
}

float max_difference(const Image& a, const Image& b) {
    float largest = 0.0f;
    for (std::size_t i = 0; i < a.pixels.size(); ++i)
        largest = std::max(largest, max_component(abs(a.pixels[i] - b.pixels[i])));
    return largest;
}

double fraction_differing(const Image& a, const Image& b, float tolerance) {
    std::size_t differing = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i)
        differing += max_component(abs(a.pixels[i] - b.pixels[i])) > tolerance ? 1 : 0;
    return static_cast<double>(differing) / static_cast<double>(a.pixels.size());
}

// ---------------------------------------------------------------------------------------------------------
// A lit wall at z = -5 seen from z = 5, lit from the side so that nothing between the camera and the wall
// can shadow it.
Scene lit_wall() {
    Scene scene;
    scene.ambient = Vec3f(0.1f);
    scene.background = Vec3f(0.0f, 0.0f, 0.3f);
    const std::uint32_t wall = add_material(scene, diffuse({0.8f, 0.6f, 0.4f}));
    add_quad(scene, {-20, -20, -5}, {20, -20, -5}, {20, 20, -5}, {-20, 20, -5}, wall);
    scene.lights.push_back({{6.0f, 0.0f, -2.0f}, Vec3f(1.0f)});
    return scene;
}

TEST(Whitted, GlassOfIndexOneAndFullTransmissionIsInvisible) {
    const Camera camera = look({0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 40.0f, 32, 32);
    const Scene empty = lit_wall();
    Scene with_glass = lit_wall();
    with_glass.spheres.push_back({{0, 0, 0}, 1.0f, add_material(with_glass, glass(1.0f))});
    const Image reference = render_brute(empty, camera, whitted());
    const Image through_glass = render_brute(with_glass, camera, whitted());
    EXPECT_LT(max_difference(reference, through_glass), 1e-4f);

    // The sphere covers the middle of the picture: made opaque, it shows.
    with_glass.materials.back() = diffuse(Vec3f(0.5f));
    EXPECT_GT(max_difference(reference, render_brute(with_glass, camera, whitted())), 0.05f);
}

// A mirror z = 0 in front of the camera, a checkered wall z = 10 and a red ball behind the camera, lit
// from between: the picture must be that of the same wall and ball mirrored through z = 0, seen directly.
TEST(Whitted, MirrorShowsTheSceneMirrored) {
    const Camera camera = look({0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 60.0f, 48, 32);
    auto scene_with = [](float side) {
        Scene scene;
        scene.ambient = Vec3f(0.1f);
        const std::uint32_t wall = add_material(scene, diffuse(Vec3f(0.9f)));
        const std::uint32_t red = add_material(scene, diffuse({0.9f, 0.1f, 0.1f}));
        scene.planes.push_back({{0.0f, 0.0f, -side}, -10.0f, wall, true});
        scene.spheres.push_back({{-3.0f, 2.0f, 8.0f * side}, 1.5f, red});
        scene.lights.push_back({{0.0f, 0.0f, 7.0f * side}, Vec3f(1.0f)});
        return scene;
    };
    Scene mirrored = scene_with(1.0f);
    mirrored.planes.push_back({{0.0f, 0.0f, 1.0f}, 0.0f, add_material(mirrored, mirror(1.0f)), false});
    const Image in_mirror = render_brute(mirrored, camera, whitted());
    const Image direct = render_brute(scene_with(-1.0f), camera, whitted());
    // Checker edges may fall on either side of a pixel centre after the bounce's rounding.
    EXPECT_LT(fraction_differing(in_mirror, direct, 1e-3f), 0.02);
    // The ball is up and to the left in both (not flipped).
    const Vec3f ball = in_mirror.at(17, 11);
    EXPECT_GT(ball.x, 2.0f * ball.y) << "pixel (17, 11) should show the red ball";
}

// A light above an opaque ceiling, the camera and a floor below it: only the ambient term is left, with the
// ceiling as a mesh (Accel::occluded) and as a plane (the planes' occlusion test).
TEST(Whitted, LightBehindAnOpaqueWallLightsNothing) {
    const Camera camera = look({0, 2, 6}, {0, 0, 0}, {0, 1, 0}, 60.0f, 24, 24);
    for (const bool plane_ceiling : {false, true}) {
        SCOPED_TRACE(plane_ceiling ? "plane ceiling" : "mesh ceiling");
        Scene scene;
        scene.ambient = Vec3f(0.2f);
        const Vec3f color(0.5f, 0.7f, 0.9f);
        const std::uint32_t matte = add_material(scene, diffuse(color));
        scene.planes.push_back({{0.0f, 1.0f, 0.0f}, 0.0f, matte, false});
        scene.lights.push_back({{0.0f, 10.0f, 0.0f}, Vec3f(1.0f)});
        const Image lit = render_brute(scene, camera, whitted());
        if (plane_ceiling) {
            scene.planes.push_back({{0.0f, -1.0f, 0.0f}, -5.0f, matte, false});
        } else {
            add_quad(scene, {-1e3f, 5, -1e3f}, {-1e3f, 5, 1e3f}, {1e3f, 5, 1e3f}, {1e3f, 5, -1e3f}, matte);
        }
        const Image dark = render_brute(scene, camera, whitted());
        for (const Vec3f& pixel : dark.pixels) {
            EXPECT_NEAR(pixel.x, 0.2f * color.x, 1e-6f);
            EXPECT_NEAR(pixel.y, 0.2f * color.y, 1e-6f);
            EXPECT_NEAR(pixel.z, 0.2f * color.z, 1e-6f);
        }
        EXPECT_GT(lit.at(12, 20).x, 0.2f * color.x + 0.1f);  // the same floor is lit without the ceiling
    }
}

// Two facing mirrors that also reflect some ambient light, the camera between them: every ray bounces until
// the depth limit, and a pixel is ambient x (1 + ks + ... + ks^(depth - 1)).
TEST(Whitted, RayTreeStopsAtTheMaximumDepth) {
    Scene scene;
    scene.ambient = Vec3f(0.2f);
    Material half_mirror = diffuse(Vec3f(1.0f));
    half_mirror.ks = 0.5f;
    const std::uint32_t material = add_material(scene, half_mirror);
    scene.planes.push_back({{0.0f, 0.0f, 1.0f}, -1.0f, material, false});
    scene.planes.push_back({{0.0f, 0.0f, -1.0f}, -1.0f, material, false});
    const Camera camera = look({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 30.0f, 5, 4);
    for (const int depth : {1, 2, 5, 8}) {
        SCOPED_TRACE(depth);
        RenderOptions options = whitted();
        options.max_depth = depth;
        RenderStats stats;
        const Image image = render_brute(scene, camera, options, &stats);
        EXPECT_EQ(stats.primary_rays, 20u);
        EXPECT_EQ(stats.reflection_rays, 20u * static_cast<std::uint64_t>(depth - 1));
        EXPECT_EQ(stats.refraction_rays, 0u);
        EXPECT_EQ(stats.shadow_rays, 0u);
        const double expected = 0.2 * (1.0 - std::pow(0.5, depth)) / 0.5;
        for (const Vec3f& pixel : image.pixels)
            EXPECT_NEAR(pixel.x, expected, 1e-6);
    }
}

TEST(Whitted, MinimumWeightCutsOffFaintRays) {
    Scene scene;
    scene.ambient = Vec3f(0.2f);
    Material half_mirror = diffuse(Vec3f(1.0f));
    half_mirror.ks = 0.5f;
    const std::uint32_t material = add_material(scene, half_mirror);
    scene.planes.push_back({{0.0f, 0.0f, 1.0f}, -1.0f, material, false});
    scene.planes.push_back({{0.0f, 0.0f, -1.0f}, -1.0f, material, false});
    RenderOptions options = whitted();
    options.max_depth = 10;
    options.min_weight = 0.1f;  // 0.5, 0.25 and 0.125 pass; 0.0625 does not
    RenderStats stats;
    (void)render_brute(scene, look({0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 30.0f, 2, 2), options, &stats);
    EXPECT_EQ(stats.reflection_rays, 4u * 3u);
}

// Snell's window: under a glass surface (index 1.5) looking up, rays within the critical angle
// asin(1 / 1.5) = 41.8 degrees of the normal leave to the white sky; past it they are totally reflected down
// to a black floor.
TEST(Whitted, TotalInternalReflectionPastTheCriticalAngleOnly) {
    Scene scene;
    scene.background = Vec3f(1.0f);
    scene.ambient = Vec3f(0.0f);
    scene.planes.push_back({{0.0f, 1.0f, 0.0f}, 0.0f, add_material(scene, glass(1.5f)), false});
    Material black = diffuse(Vec3f(0.0f));
    scene.planes.push_back({{0.0f, 1.0f, 0.0f}, -10.0f, add_material(scene, black), false});
    const Camera camera = look({0, -1, 0}, {0, 0, 0}, {0, 0, 1}, 130.0f, 41, 41);
    RenderStats stats;
    const Image image = render_brute(scene, camera, whitted(), &stats);

    const PinholeCamera pinhole(camera);
    const double critical_degrees = std::asin(1.0 / 1.5) * 180.0 / std::numbers::pi;
    int inside = 0, outside = 0;
    for (int y = 0; y < camera.height; ++y) {
        for (int x = 0; x < camera.width; ++x) {
            const Ray ray = pinhole.generate(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f);
            const double angle =
                std::acos(ray.direction.y / length(ray.direction)) * 180.0 / std::numbers::pi;
            if (angle < critical_degrees - 0.5) {
                ++inside;
                EXPECT_EQ(image.at(x, y), Vec3f(1.0f)) << x << ", " << y << " at " << angle << " degrees";
            } else if (angle > critical_degrees + 0.5) {
                ++outside;
                EXPECT_EQ(image.at(x, y), Vec3f(0.0f)) << x << ", " << y << " at " << angle << " degrees";
            }
        }
    }
    EXPECT_GT(inside, 100);
    EXPECT_GT(outside, 100);
    EXPECT_GT(stats.refraction_rays, 0u);
    EXPECT_GT(stats.reflection_rays, 0u);  // the total internal reflections
}

// A triangle facing +z whose vertex normals all lean 45 degrees, lit head-on from far away: the diffuse
// term uses the interpolated normal, cos 45 degrees, not the facet's 1.
TEST(Whitted, SmoothNormalsShadeTheDiffuseTerm) {
    Scene scene;
    scene.ambient = Vec3f(0.0f);
    const std::uint32_t white = add_material(scene, diffuse(Vec3f(1.0f)));
    add_quad(scene, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, white);
    scene.lights.push_back({{0.0f, 0.0f, 1e4f}, Vec3f(1.0f)});
    const Camera camera = look({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 10.0f, 1, 1);
    EXPECT_NEAR(render_brute(scene, camera, whitted()).at(0, 0).x, 1.0f, 1e-5f);
    scene.meshes[0].normals.assign(4, normalize(Vec3f(1.0f, 0.0f, 1.0f)));
    EXPECT_NEAR(render_brute(scene, camera, whitted()).at(0, 0).x, std::sqrt(0.5f), 1e-5f);
}

// ---------------------------------------------------------------------------------------------------------
// Everything at once: a glass ball, a mirror ball, a glass icosphere mesh with vertex normals, a floor
// (checkered on a unit grid), two lights; `scale` times its size around `origin`.
Scene showcase(Vec3f origin = Vec3f(0.0f), float scale = 1.0f, bool checkered = true) {
    Scene scene;
    scene.ambient = Vec3f(0.15f);
    scene.background = Vec3f(0.1f, 0.1f, 0.2f);
    Material floor = diffuse({0.9f, 0.9f, 0.85f});
    floor.ks = 0.2f;
    const std::uint32_t floor_material = add_material(scene, floor);
    Material chrome = mirror(0.8f);
    chrome.kd = 0.2f;
    chrome.shininess = 50.0f;
    Material tinted_glass = glass(1.5f);
    tinted_glass.ks = 0.1f;
    tinted_glass.kt = 0.85f;
    tinted_glass.shininess = 200.0f;
    const std::uint32_t chrome_material = add_material(scene, chrome);
    const std::uint32_t glass_material = add_material(scene, tinted_glass);
    const std::uint32_t red = add_material(scene, diffuse({0.8f, 0.2f, 0.1f}));
    scene.planes.push_back({{0.0f, 1.0f, 0.0f}, origin.y, floor_material, checkered});
    scene.spheres.push_back({origin + scale * Vec3f(-1.2f, 0.8f, 0.0f), scale * 0.8f, chrome_material});
    scene.spheres.push_back({origin + scale * Vec3f(1.0f, 0.6f, 0.8f), scale * 0.6f, glass_material});
    scene.spheres.push_back({origin + scale * Vec3f(0.6f, 0.4f, -1.4f), scale * 0.4f, red});
    TriangleMesh ball = make_icosphere(2, origin + scale * Vec3f(0.0f, 0.5f, 1.6f), scale * 0.5f);
    ball.material = glass_material;
    scene.meshes.push_back(ball);
    scene.lights.push_back({origin + scale * Vec3f(-3.0f, 5.0f, 4.0f), Vec3f(0.6f)});
    scene.lights.push_back({origin + scale * Vec3f(4.0f, 3.0f, -2.0f), Vec3f(0.5f)});
    return scene;
}

Camera showcase_camera(Vec3f origin = Vec3f(0.0f), float scale = 1.0f, int width = 40, int height = 30) {
    return look(origin + scale * Vec3f(0.0f, 2.0f, 6.0f), origin + scale * Vec3f(0.0f, 0.5f, 0.0f), {0, 1, 0},
                45.0f, width, height);
}

TEST(Whitted, SameBitsWhateverThreadsAndTiles) {
    const Scene scene = showcase();
    const Camera camera = showcase_camera();
    RenderOptions reference_options = whitted(4);
    reference_options.threads = 1;
    reference_options.tile_size = 16;
    const Image reference = render_brute(scene, camera, reference_options);
    for (const int threads : {2, 3, 0}) {
        for (const int tile_size : {1, 7, 64}) {
            SCOPED_TRACE(testing::Message() << threads << " threads, tiles of " << tile_size);
            RenderOptions options = reference_options;
            options.threads = threads;
            options.tile_size = tile_size;
            const Image image = render_brute(scene, camera, options);
            ASSERT_EQ(image.pixels.size(), reference.pixels.size());
            EXPECT_EQ(std::memcmp(image.pixels.data(), reference.pixels.data(),
                                  image.pixels.size() * sizeof(Vec3f)),
                      0);
        }
    }
}

TEST(Whitted, EveryStructureRendersTheSamePicture) {
    const Scene scene = showcase();
    const Camera camera = showcase_camera();
    RenderStats reference_stats;
    const Image reference = render_brute(scene, camera, whitted(), &reference_stats);
    EXPECT_GT(reference_stats.refraction_rays, 0u);
    EXPECT_GT(reference_stats.reflection_rays, 0u);
    EXPECT_GT(reference_stats.shadow_rays, 0u);
    for (const std::string_view name : accel_names()) {
        SCOPED_TRACE(name);
        RenderStats stats;
        const Image image = render_with(name, scene, camera, whitted(), &stats);
        EXPECT_LT(fraction_differing(image, reference, 1e-3f), 0.005);
        EXPECT_NEAR(static_cast<double>(stats.total_rays()),
                    static_cast<double>(reference_stats.total_rays()),
                    0.005 * static_cast<double>(reference_stats.total_rays()));
    }
}

// The showcase 100 times larger and 10^4 units away in every axis, where one ulp of a coordinate is 2^-10
// and hit points are off their surface by a few of them: a fixed epsilon of the scene's scale would leave
// secondary rays on their own surface. Lighting has no fall-off, so the picture must stay the picture of the
// unit-sized scene at the origin (no acne of self-shadowing, self-reflection or self-refraction).
TEST(Whitted, NoAcneFarFromTheOrigin) {
    const Vec3f far(1.2e4f, 1.1e4f, -1.3e4f);
    const Image near_origin = render_brute(showcase(Vec3f(0.0f), 1.0f, false),
                                           showcase_camera(Vec3f(0.0f), 1.0f, 64, 48), whitted());
    const Image far_away =
        render_brute(showcase(far, 100.0f, false), showcase_camera(far, 100.0f, 64, 48), whitted());
    EXPECT_LT(fraction_differing(near_origin, far_away, 0.05f), 0.01);
}

TEST(Whitted, SamplesPerPixelAverageStratifiedSamples) {
    // Left half white, right half black, the edge through the middle of pixel 1 of 3.
    Scene scene;
    scene.ambient = Vec3f(1.0f);
    const std::uint32_t white = add_material(scene, diffuse(Vec3f(1.0f)));
    add_quad(scene, {-10, -10, 0}, {0, -10, 0}, {0, 10, 0}, {-10, 10, 0}, white);
    const Camera camera = look({0, 0, 1}, {0, 0, 0}, {0, 1, 0}, 90.0f, 3, 1);
    RenderStats stats;
    const Image image = render_brute(scene, camera, whitted(16), &stats);
    EXPECT_EQ(stats.primary_rays, 3u * 16u);
    EXPECT_EQ(image.at(0, 0), Vec3f(1.0f));
    EXPECT_EQ(image.at(2, 0), Vec3f(0.0f));
    EXPECT_NEAR(image.at(1, 0).x, 0.5f, 1e-6f);  // 8 of the 16 columns of samples on each side
}

TEST(Whitted, RejectsBadOptions) {
    const Scene scene = showcase();
    const Camera camera = showcase_camera();
    RenderOptions no_samples = whitted(0);
    EXPECT_THROW((void)render_brute(scene, camera, no_samples), std::invalid_argument);
    RenderOptions no_depth = whitted();
    no_depth.max_depth = 0;
    EXPECT_THROW((void)render_brute(scene, camera, no_depth), std::invalid_argument);
    RenderOptions negative_weight = whitted();
    negative_weight.min_weight = -1.0f;
    EXPECT_THROW((void)render_brute(scene, camera, negative_weight), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
