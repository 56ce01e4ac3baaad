// The kernels on a GPU against the CPU structures on the same rays (docs/cuda.md): the same hit or miss, the
// same triangle or a tie, t within 1e-5 relative (compare_hits); bit-identical answers are counted and
// printed, since the kernels are built to give them (--fmad=false, IEEE division and square root). Without a
// device these tests skip, saying why; the tracer's refusal without a device is tested everywhere.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

#include "lancer/agreement.hpp"
#include "lancer/camera.hpp"
#include "lancer/cuda.hpp"
#include "lancer/load_scene.hpp"
#include "support/ray_sets.hpp"
#include "support/test_scenes.hpp"

namespace lancer {
namespace {

constexpr CudaKernel kKernels[] = {CudaKernel::Plucker, CudaKernel::WhileWhile,
                                   CudaKernel::SpeculativeWhileWhile, CudaKernel::Persistent,
                                   CudaKernel::CompressedWide};

// Each kernel on its structure's default build; the walk also on the other three Plücker layouts (without
// the 2:1 rule, with computed boxes).
struct Configuration {
    CudaKernel kernel;
    bool balanced = true, stored_boxes = true;
};
constexpr Configuration kConfigurations[] = {
    {CudaKernel::Plucker, true, true},  {CudaKernel::Plucker, true, false},
    {CudaKernel::Plucker, false, true}, {CudaKernel::Plucker, false, false},
    {CudaKernel::WhileWhile},           {CudaKernel::SpeculativeWhileWhile},
    {CudaKernel::Persistent},           {CudaKernel::CompressedWide}};

std::size_t bit_identical(std::span<const Hit> expected, std::span<const Hit> actual) {
    std::size_t same = 0;
    for (std::size_t i = 0; i < expected.size(); ++i)
        same += std::memcmp(&expected[i], &actual[i], sizeof(Hit)) == 0 ? 1 : 0;
    return same;
}

// The any-hit kernels against Accel::occluded, byte for byte: the batch as it is, then each ray ending just
// before or exactly at its closest hit (a shadow ray's interval), alternately, so that the interval's end
// decides. The batch is uploaded once and traced twice, as the benchmark traces it.
void expect_occlusion_agrees(const Accel& accel, CudaTracer& tracer, std::span<const Ray> batch,
                             const std::string& name) {
    const std::vector<Hit> closest = testing::trace_in_parallel(accel, batch);
    std::vector<Ray> shortened(batch.begin(), batch.end());
    for (std::size_t i = 0; i < shortened.size(); ++i) {
        if (closest[i].hit())
            shortened[i].tfar = i % 2 == 0 ? closest[i].t : std::nextafter(closest[i].t, 0.0f);
    }
    for (const std::span<const Ray> rays : {batch, std::span<const Ray>(shortened)}) {
        std::vector<std::uint8_t> expected(rays.size());
        accel.occluded(rays, expected);
        tracer.upload_rays(rays);
        for (int repeat = 0; repeat < 2; ++repeat) {
            const CudaTrace traced = tracer.trace_uploaded(true);
            ASSERT_EQ(traced.occluded.size(), rays.size());
            EXPECT_TRUE(traced.hits.empty());
            std::size_t differ = 0, occluded = 0;
            for (std::size_t i = 0; i < rays.size(); ++i) {
                differ += expected[i] != traced.occluded[i] ? 1 : 0;
                occluded += expected[i];
            }
            std::printf("%s, occlusion%s: %zu of %zu occluded, %zu differ, kernel %.3f ms\n", name.c_str(),
                        rays.data() == batch.data() ? "" : " (intervals ending at the hit)", occluded,
                        rays.size(), differ, traced.kernel_ms);
            EXPECT_EQ(differ, 0u) << name;
            EXPECT_GT(occluded, 0u) << name;
        }
    }
}

// Every kernel, both triangle tests, a batch of rays and a frame of the canonical camera; the batch's
// occlusion too.
void expect_kernels_agree(const Geometry& geometry, std::span<const Ray> batch, const Camera& camera,
                          const std::string& scene_name) {
    const testing::RaySet frame = testing::canonical_view_rays(geometry.bounds(), camera.width);
    for (const TriangleTest test : {TriangleTest::MollerTrumbore, TriangleTest::Watertight}) {
        for (const auto& [kernel, balanced, stored_boxes] : kConfigurations) {
            const std::unique_ptr<Accel> accel = make_accel(cuda_kernel_structure(kernel));
            BuildOptions options = build_options(test);
            set_build_option(options, std::string("plucker.balanced=") + (balanced ? "true" : "false"));
            set_build_option(options,
                             std::string("plucker.stored_boxes=") + (stored_boxes ? "true" : "false"));
            accel->build(geometry, options);
            CudaTracer tracer(*accel, geometry, test, kernel);
            const std::string name = std::string(cuda_kernel_name(kernel)) +
                                     (balanced ? "" : ", no 2:1 rule") +
                                     (stored_boxes ? "" : ", computed boxes");
            for (const bool is_frame : {false, true}) {
                const std::span<const Ray> rays = is_frame ? std::span<const Ray>(frame.rays) : batch;
                const std::vector<Hit> expected = testing::trace_in_parallel(*accel, rays);
                const CudaTrace traced = is_frame ? tracer.trace_frame(camera) : tracer.trace(rays);
                ASSERT_EQ(traced.hits.size(), rays.size());
                const Agreement agreement = compare_hits(rays, expected, traced.hits);
                std::printf("%s, %s, %s, %s: %s, %zu bit-identical, kernel %.3f ms\n", scene_name.c_str(),
                            is_frame ? "frame" : "batch", name.c_str(),
                            test == TriangleTest::Watertight ? "watertight" : "moller",
                            agreement.summary().c_str(), bit_identical(expected, traced.hits),
                            traced.kernel_ms);
                EXPECT_EQ(agreement.mismatches, 0u)
                    << scene_name << ", " << name << ": " << agreement.summary();
                EXPECT_GT(agreement.hits, 0u);
            }
            expect_occlusion_agrees(*accel, tracer, batch, scene_name + ", " + name);
        }
    }
}

TEST(CudaGpu, KernelsAgreeWithTheCpuOnATriangleScene) {
    std::string why;
    if (!cuda_available(&why)) GTEST_SKIP() << why;
    const std::vector<Triangle> triangles = testing::knot_triangles(400);
    const Geometry geometry{triangles, {}};
    const testing::RaySet random = testing::random_rays(geometry.bounds(), 200'000, 31);
    testing::RaySet hostile = testing::hostile_rays(geometry.bounds());
    std::vector<Ray> batch = random.rays;
    batch.insert(batch.end(), hostile.rays.begin(), hostile.rays.end());
    expect_kernels_agree(geometry, batch, canonical_view(geometry.bounds(), 256, 256), "torus knot");
}

// Scenes at the coordinate domain's edges (docs/numerical-contract.md, "Coordinate domain"): the knot scaled
// to 2^60 and to 2^-60, which the structures see scaled back into the ordinary range; the tracer traces the
// same arrays and conditions its rays, a frame's included, as the CPU does.
TEST(CudaGpu, KernelsAgreeWithTheCpuOnScenesAtTheDomainsEdges) {
    std::string why;
    if (!cuda_available(&why)) GTEST_SKIP() << why;
    for (const int exponent : {58, -60}) {
        std::vector<Triangle> triangles = testing::knot_triangles(100);
        for (Triangle& triangle : triangles) {
            for (Vec3f* vertex : {&triangle.v0, &triangle.v1, &triangle.v2}) {
                *vertex = {std::ldexp(vertex->x, exponent), std::ldexp(vertex->y, exponent),
                           std::ldexp(vertex->z, exponent)};
            }
        }
        const Geometry geometry{triangles, {}};
        const testing::RaySet random = testing::random_rays(geometry.bounds(), 50'000, 32);
        expect_kernels_agree(geometry, random.rays, canonical_view(geometry.bounds(), 128, 128),
                             "torus knot x 2^" + std::to_string(exponent));
    }
}

// The heatmap's counts: the GPU walk enters the leaves the CPU walk enters, ray by ray; from the canonical
// camera, whose rays the kernel makes, and from a camera far from the scene, whose frame the tracer makes and
// conditions on the host as a batch.
TEST(CudaGpu, PluckerStepsAreTheCpuWalksLeaves) {
    std::string why;
    if (!cuda_available(&why)) GTEST_SKIP() << why;
    const std::vector<Triangle> triangles = testing::knot_triangles(300);
    const Geometry geometry{triangles, {}};
    const Camera canonical = canonical_view(geometry.bounds(), 128, 128);
    Camera far = canonical;
    far.eye = far.look_at + (canonical.eye - canonical.look_at) * 16.0f;
    far.vertical_fov_degrees = canonical.vertical_fov_degrees / 16.0f;
    // Without the 2:1 rule the steps take in the inner cells the links descend, as on the CPU.
    for (const bool balanced : {true, false}) {
        BuildOptions options;
        set_build_option(options, std::string("plucker.balanced=") + (balanced ? "true" : "false"));
        const std::unique_ptr<Accel> accel = make_accel("plucker");
        accel->build(geometry, options);
        CudaTracer tracer(*accel, geometry, TriangleTest::MollerTrumbore, CudaKernel::Plucker);
        for (const bool far_camera : {false, true}) {
            const Camera& camera = far_camera ? far : canonical;
            const std::vector<Ray> frame =
                PinholeCamera(camera).pixel_centre_rays(0, 0, camera.width, camera.height);
            const CudaTrace traced = tracer.trace_frame(camera, true);
            ASSERT_EQ(traced.steps.size(), frame.size());
            std::size_t hits = 0;
            for (std::size_t i = 0; i < frame.size(); ++i) {
                Hit hit;
                TraversalCounters counters;
                accel->intersect({&frame[i], 1}, {&hit, 1}, &counters);
                hits += hit.hit() ? 1 : 0;
                ASSERT_EQ(traced.steps[i], counters.nodes_visited)
                    << (balanced ? "2:1" : "unconstrained") << (far_camera ? ", far camera" : "") << ", ray "
                    << i;
            }
            EXPECT_GT(hits, frame.size() / 10) << "the camera must see the knot";
        }
    }
}

TEST(CudaGpu, KernelsAgreeWithTheCpuOnTheStanfordMeshes) {
    std::string why;
    if (!cuda_available(&why)) GTEST_SKIP() << why;
    for (const char* name : {"bunny.obj", "armadillo.off", "dragon.ply"}) {
        const std::filesystem::path file = std::filesystem::path(LANCER_SHARED_DIR) / "data/meshes" / name;
        if (!std::filesystem::exists(file))
            GTEST_SKIP() << file << " is absent (see README, 'The Stanford meshes')";
        const Scene scene = load_scene(file);
        const SceneGeometry geometry(scene);
        const testing::RaySet random = testing::random_rays(geometry.view().bounds(), 1'000'000, 32);
        expect_kernels_agree(geometry.view(), random.rays, canonical_view(geometry.view().bounds()), name);
    }
}

// Here on every machine: without a device (or without CUDA) the tracer refuses at once, saying why.
TEST(CudaGpu, WithoutADeviceTheTracerSaysWhy) {
    std::string why;
    if (cuda_available(&why)) GTEST_SKIP() << "a CUDA device is present: the refusal cannot be observed";
    EXPECT_TRUE(why.starts_with("no CUDA device (cudaGetDeviceCount: ") ||
                why.starts_with("built without CUDA"))
        << why;
    const std::vector<Triangle> triangles = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    const std::unique_ptr<Accel> accel = make_accel("bvh");
    accel->build({triangles, {}}, {});
    try {
        CudaTracer tracer(*accel, {triangles, {}}, TriangleTest::MollerTrumbore, CudaKernel::Persistent);
        ADD_FAILURE() << "CudaTracer was made without a device";
    } catch (const CudaError& error) {
        EXPECT_EQ(std::string(error.what()), why);
    }
}

TEST(CudaGpu, KernelNamesRoundTrip) {
    for (const CudaKernel kernel : kKernels)
        EXPECT_EQ(parse_cuda_kernel(cuda_kernel_name(kernel)), kernel);
    EXPECT_THROW((void)parse_cuda_kernel("warp-speed"), std::invalid_argument);
    EXPECT_EQ(default_cuda_kernel("plucker"), CudaKernel::Plucker);
    EXPECT_EQ(default_cuda_kernel("bvh"), CudaKernel::Persistent);
    EXPECT_EQ(default_cuda_kernel("bvh8"), CudaKernel::CompressedWide);
    // Each structure's default kernel traces that structure.
    for (const CudaKernel kernel : kKernels) {
        const std::string_view structure = cuda_kernel_structure(kernel);
        EXPECT_EQ(cuda_kernel_structure(default_cuda_kernel(structure)), structure);
    }
    EXPECT_THROW((void)default_cuda_kernel("kdtree"), std::invalid_argument);
}

}  // namespace
}  // namespace lancer
