// The lancer executable end to end: the RAYS/HITS round trip, exit code 2 with a clear message on bad
// input, and renders that produce a PNG or an OpenEXR.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "lancer/ray.hpp"
#include "support/instanced_gltf.hpp"

namespace lancer {
namespace {

namespace fs = std::filesystem;

struct Result {
    int exit_code;
    std::string output;  // stdout and stderr together
};

class Cli : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() /
               ("lancer_cli_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    fs::path write(const std::string& name, const std::string& text) const {
        const fs::path path = dir_ / name;
        std::ofstream(path, std::ios::binary) << text;
        return path;
    }

    Result run(const std::string& arguments) const {
        const fs::path log = dir_ / "log.txt";
        const std::string command =
            std::string(LANCER_EXECUTABLE) + " " + arguments + " >" + log.string() + " 2>&1";
        const int status = std::system(command.c_str());
        std::ostringstream text;
        text << std::ifstream(log).rdbuf();
        return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text.str()};
    }

    fs::path dir_;
};

// A quad (fan-triangulated into triangles 0 and 1) and a triangle (2) behind it.
const char* kMesh =
    "OFF\n"
    "7 2 0\n"
    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
    "0 0 -1\n2 0 -1\n0 2 -1\n"
    "4 0 1 2 3\n"
    "3 4 5 6\n";

// lancer nearest: the nearest point of the quad or of the triangle behind it, read back from the binary file.
TEST_F(Cli, NearestWritesTheNearestSurfacePoints) {
    const fs::path mesh = write("mesh.off", kMesh);
    const std::vector<Vec3f> points = {{0.7f, 0.2f, 0.5f}, {0.5f, 1.5f, 0.0f}, {1.5f, 0.2f, -2.0f}};
    const fs::path points_file = dir_ / "points.bin";
    std::ofstream(points_file, std::ios::binary)
        .write(reinterpret_cast<const char*>(points.data()),
               static_cast<std::streamsize>(points.size() * sizeof(Vec3f)));
    const fs::path nearest_file = dir_ / "nearest.bin";
    const Result result = run("nearest " + mesh.string() + " --points " + points_file.string() +
                              " --nearest " + nearest_file.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    struct Record {
        float x, y, z, distance;
        std::int32_t prim;
        float u, v;
    };
    std::vector<Record> nearest(points.size());
    std::ifstream in(nearest_file, std::ios::binary);
    in.read(reinterpret_cast<char*>(nearest.data()),
            static_cast<std::streamsize>(nearest.size() * sizeof(Record)));
    ASSERT_EQ(in.gcount(), static_cast<std::streamsize>(nearest.size() * sizeof(Record)));
    EXPECT_EQ(nearest[0].prim, 0);  // above triangle 0 of the quad
    EXPECT_FLOAT_EQ(nearest[0].distance, 0.5f);
    EXPECT_FLOAT_EQ(nearest[0].z, 0.0f);
    EXPECT_FLOAT_EQ(nearest[1].distance, 0.5f);  // beside the quad's upper edge y = 1
    EXPECT_FLOAT_EQ(nearest[1].y, 1.0f);
    EXPECT_EQ(nearest[2].prim, 2);  // below the triangle at z = -1
    EXPECT_FLOAT_EQ(nearest[2].distance, 1.0f);
    // A points file that is not whole points is refused with the file named.
    const fs::path broken = write("broken.bin", "12345");
    const Result refused = run("nearest " + mesh.string() + " --points " + broken.string() + " --nearest " +
                               nearest_file.string());
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_NE(refused.output.find("not a whole number of 12-byte points"), std::string::npos)
        << refused.output;
}

TEST_F(Cli, RaysRoundTripMatchesTheLibrary) {
    const fs::path mesh = write("mesh.off", kMesh);
    std::vector<Ray> rays = {
        {{0.7f, 0.2f, 1.0f}, {0, 0, -1}, 0.0f, kInfinity},  // triangle 0 of the fan (0 1 2)
        {{0.2f, 0.7f, 1.0f}, {0, 0, -1}, 0.0f, kInfinity},  // triangle 1 of the fan (0 2 3)
        {{1.5f, 0.2f, 1.0f}, {0, 0, -1}, 0.0f, kInfinity},  // beside the quad: the triangle behind
        {{1.5f, 1.5f, 1.0f}, {0, 0, -1}, 0.0f, kInfinity},  // miss
        {{0.7f, 0.2f, 1.0f}, {0, 0, 0}, 0.0f, kInfinity},   // zero direction: miss
        {{0.7f, 0.2f, 1.0f}, {0, 0, -1}, 3.0f, 2.0f},       // tnear > tfar: miss
    };
    const fs::path rays_file = dir_ / "rays.bin";
    std::ofstream(rays_file, std::ios::binary)
        .write(reinterpret_cast<const char*>(rays.data()),
               static_cast<std::streamsize>(rays.size() * sizeof(Ray)));
    const fs::path hits_file = dir_ / "hits.bin";

    for (const char* extra : {"", " --watertight"}) {
        const Result result = run("rays " + mesh.string() + " --rays " + rays_file.string() + " --hits " +
                                  hits_file.string() + extra);
        ASSERT_EQ(result.exit_code, 0) << result.output;
        std::vector<Hit> hits(rays.size());
        std::ifstream in(hits_file, std::ios::binary);
        in.read(reinterpret_cast<char*>(hits.data()),
                static_cast<std::streamsize>(hits.size() * sizeof(Hit)));
        ASSERT_EQ(in.gcount(), static_cast<std::streamsize>(hits.size() * sizeof(Hit)));

        EXPECT_EQ(hits[0].prim, 0);
        EXPECT_FLOAT_EQ(hits[0].t, 1.0f);
        EXPECT_FLOAT_EQ(hits[0].u, 0.5f);  // (0.7, 0.2) = 0.3 v0 + 0.5 v1 + 0.2 v2 of triangle (0 1 2)
        EXPECT_FLOAT_EQ(hits[0].v, 0.2f);
        EXPECT_EQ(hits[1].prim, 1);
        EXPECT_EQ(hits[2].prim, 2);
        EXPECT_FLOAT_EQ(hits[2].t, 2.0f);
        for (int i = 3; i < 6; ++i) {
            EXPECT_EQ(hits[static_cast<std::size_t>(i)].prim, -1);
            EXPECT_EQ(hits[static_cast<std::size_t>(i)].t, kInfinity);
        }
    }
}

TEST_F(Cli, BadInputExitsWithTwoAndSaysWhere) {
    const fs::path broken = write("broken.off", "OFF\n3 1 0\n0 0 0\n1 0 x\n0 1 0\n3 0 1 2\n");
    const fs::path rays = write("rays.bin", std::string(33, '\0'));
    const fs::path good = write("good.off", kMesh);
    const fs::path hits = dir_ / "hits.bin";

    Result result = run("info " + broken.string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("broken.off:4"), std::string::npos) << result.output;

    result = run("info " + (dir_ / "missing.off").string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("missing.off"), std::string::npos) << result.output;

    result = run("rays " + good.string() + " --rays " + rays.string() + " --hits " + hits.string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("32-byte"), std::string::npos) << result.output;

    result = run("render " + good.string() + " --accel nope -o " + (dir_ / "x.png").string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("brute"), std::string::npos) << result.output;

    result = run("render " + good.string() + " --size 12 -o " + (dir_ / "x.png").string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("WIDTHxHEIGHT"), std::string::npos) << result.output;

    // An option that takes one of a few names says which, in order.
    result = run("render " + good.string() + " --mode sepia");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("--mode: 'sepia' is not one of whitted, flat, normal, depth, heatmap"),
              std::string::npos)
        << result.output;
    result = run("rays " + good.string() + " --rays " + rays.string() + " --hits " + hits.string() +
                 " --device gpu");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("--device: 'gpu' is not one of cpu, cuda"), std::string::npos)
        << result.output;
    result = run("render " + good.string() + " --device cuda --cuda-kernel fast");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("--cuda-kernel: 'fast' is not one of plucker, while-while, speculative, "
                                 "persistent"),
              std::string::npos)
        << result.output;

    // The scaling bench needs the ranks of an mpirun job (docs/distributed.md).
    result = run("bench --mpi --mesh " + good.string() + " --accel bvh --frames 1 --size 8");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("under mpirun"), std::string::npos) << result.output;
}

// --device cuda (issue 7): render takes --mode flat or heatmap only, on any machine; without a usable GPU
// every command refuses with exit code 2 and says why; with one, `rays` answers as the CPU does.
TEST_F(Cli, DeviceCudaRefusesClearlyOrAgreesWithTheCpu) {
    const fs::path good = write("good.off", kMesh);
    Result result =
        run("render " + good.string() + " --device cuda --mode whitted -o " + (dir_ / "x.png").string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("--mode flat or heatmap only"), std::string::npos) << result.output;

    const std::vector<Ray> rays = {{{0.7f, 0.2f, 1}, {0, 0, -1}, 0.0f, kInfinity},
                                   {{1.5f, 0.2f, 1}, {0, 0, -1}, 0.0f, kInfinity},
                                   {{5, 5, 1}, {0, 0, -1}, 0.0f, kInfinity}};
    const fs::path rays_file = dir_ / "rays.bin";
    std::ofstream(rays_file, std::ios::binary)
        .write(reinterpret_cast<const char*>(rays.data()),
               static_cast<std::streamsize>(rays.size() * sizeof(Ray)));
    const std::string arguments = "rays " + good.string() + " --rays " + rays_file.string() + " --hits ";
    ASSERT_EQ(run(arguments + (dir_ / "cpu.bin").string()).exit_code, 0);
    result = run(arguments + (dir_ / "gpu.bin").string() + " --device cuda");
    if (result.exit_code == 2) {
        EXPECT_TRUE(result.output.find("--device cuda: no CUDA device (cudaGetDeviceCount: ") !=
                        std::string::npos ||
                    result.output.find("built without CUDA") != std::string::npos)
            << result.output;
        EXPECT_FALSE(fs::exists(dir_ / "gpu.bin"));
        result = run("bench --device cuda --size 8 --frames 1 --mesh " + good.string());
        EXPECT_EQ(result.exit_code, 2) << result.output;
        EXPECT_NE(result.output.find("--device cuda: "), std::string::npos) << result.output;
        return;
    }
    ASSERT_EQ(result.exit_code, 0) << result.output;
    std::ifstream cpu(dir_ / "cpu.bin", std::ios::binary), gpu(dir_ / "gpu.bin", std::ios::binary);
    const std::string cpu_bytes((std::istreambuf_iterator<char>(cpu)), {});
    const std::string gpu_bytes((std::istreambuf_iterator<char>(gpu)), {});
    EXPECT_EQ(cpu_bytes, gpu_bytes);
}

TEST_F(Cli, RenderWritesAPngAndReportsItsWork) {
    const fs::path mesh = write("mesh.off", kMesh);
    const fs::path png = dir_ / "out.png";
    const Result result = run("render " + mesh.string() + " --size 40x30 --mode normal -o " + png.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("40x30"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("Mrays/s"), std::string::npos) << result.output;
    std::ifstream in(png, std::ios::binary);
    char signature[8] = {};
    in.read(signature, 8);
    EXPECT_EQ(std::string(signature + 1, 3), "PNG");
}

// -o names the format by its extension, in any case: .png or .exr; any other is refused before the scene is
// loaded (a missing scene file would be reported otherwise), and nothing is written.
TEST_F(Cli, RenderWritesTheFormatItsOutputNames) {
    const fs::path mesh = write("mesh.off", kMesh);
    for (const char* name : {"out.jpg", "out.tga", "out"}) {
        const Result result =
            run("render " + (dir_ / "missing.off").string() + " -o " + (dir_ / name).string());
        EXPECT_EQ(result.exit_code, 2) << result.output;
        EXPECT_NE(result.output.find("--output: '" + (dir_ / name).string() +
                                     "' is neither a .png nor an .exr file"),
                  std::string::npos)
            << result.output;
        EXPECT_FALSE(fs::exists(dir_ / name));
    }
    const auto first_bytes = [&](const std::string& name) {
        const Result result =
            run("render " + mesh.string() + " --size 8x6 --mode flat -o " + (dir_ / name).string());
        EXPECT_EQ(result.exit_code, 0) << result.output;
        std::ifstream in(dir_ / name, std::ios::binary);
        std::string bytes(4, '\0');
        in.read(bytes.data(), 4);
        return bytes;
    };
    EXPECT_EQ(first_bytes("upper.PNG"), "\x89PNG");
    EXPECT_EQ(first_bytes("mixed.Exr"), "\x76\x2f\x31\x01");
}

TEST_F(Cli, BenchWritesOneRecordPerStructureAndThreadCount) {
    const fs::path mesh = write("mesh.off", kMesh);
    const fs::path json = dir_ / "bench.json";
    const fs::path svg = dir_ / "bench.svg";
    const Result result = run("bench --mesh " + mesh.string() + " --accel grid,bvh --threads 1,2 --size 32 " +
                              "--frames 2 --json " + json.string() + " --svg " + svg.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    std::ostringstream text;
    text << std::ifstream(json).rdbuf();
    const std::string records = text.str();
    std::size_t count = 0;
    for (std::size_t at = records.find("\"mrays_per_s\""); at != std::string::npos;
         at = records.find("\"mrays_per_s\"", at + 1)) {
        ++count;
    }
    EXPECT_EQ(count, 4u) << records;  // 2 structures x 2 thread counts
    for (const char* field : {"\"mesh\"", "\"triangles\": 3", "\"accel\": \"bvh\"", "\"threads\": 2",
                              "\"build_ms\"", "\"memory_bytes\"", "\"mrays_min\"", "\"mrays_max\"",
                              "\"hit_fraction\"", "\"nodes_per_ray\"", "\"prims_per_ray\""}) {
        EXPECT_NE(records.find(field), std::string::npos) << field;
    }
    std::ostringstream picture;
    picture << std::ifstream(svg).rdbuf();
    EXPECT_NE(picture.str().find("<svg"), std::string::npos);
    EXPECT_NE(picture.str().find("bvh, 2 threads"), std::string::npos);

    EXPECT_EQ(run("bench --mesh " + mesh.string() + " --threads 0").exit_code, 2);
    EXPECT_EQ(run("bench --mesh " + mesh.string() + " --accel nope").exit_code, 2);
}

// --animate: per frame an update row and a rebuild row for each structure, refits for the BVHs, and a JSON
// record for each; render --animate writes one picture per frame under its pattern, the same bits on a
// second run.
TEST_F(Cli, AnimationsTimeUpdatesAndWriteOneFramePerFile) {
    const fs::path mesh = write("mesh.off", kMesh);
    const fs::path json = dir_ / "animate.json";
    Result result = run("bench --mesh " + mesh.string() +
                        " --animate 3 --accel bvh8,grid --threads 2 --size 32 " + "--json " + json.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("bvh8 update          refit"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("grid update          rebuild"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("medians over 3 frames"), std::string::npos) << result.output;
    std::ostringstream text;
    text << std::ifstream(json).rdbuf();
    std::size_t records = 0;
    for (std::size_t at = text.str().find("\"update_ms\""); at != std::string::npos;
         at = text.str().find("\"update_ms\"", at + 1)) {
        ++records;
    }
    EXPECT_EQ(records, 12u) << text.str();  // 3 frames x 2 structures x (update, rebuild)
    EXPECT_EQ(run("bench --mesh " + mesh.string() + " --animate 3 --view diffuse").exit_code, 2);
    EXPECT_EQ(run("bench --mesh " + mesh.string() + " --animate 0").exit_code, 2);
    EXPECT_EQ(run("bench --mesh " + mesh.string() + " --animate 2 --accel nope").exit_code, 2);

    for (const char* run_name : {"a", "b"}) {
        result = run("render " + mesh.string() + " --animate 2 --size 16x16 --mode depth -o " +
                     (dir_ / (std::string(run_name) + "_%03d.png")).string());
        ASSERT_EQ(result.exit_code, 0) << result.output;
    }
    for (const char* frame : {"_000.png", "_001.png"}) {
        std::ostringstream a, b;
        a << std::ifstream(dir_ / (std::string("a") + frame), std::ios::binary).rdbuf();
        b << std::ifstream(dir_ / (std::string("b") + frame), std::ios::binary).rdbuf();
        EXPECT_FALSE(a.str().empty()) << frame;
        EXPECT_EQ(a.str(), b.str()) << frame;
    }
    result = run("render " + mesh.string() + " --animate 2 -o " + (dir_ / "still.png").string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("must name each frame with one %d"), std::string::npos) << result.output;
}

// --subdivide N: each mesh with 4^N times its triangles, named with the level; beyond 4, refused.
TEST_F(Cli, BenchSubdividesTheMeshes) {
    const fs::path mesh = write("mesh.off", kMesh);
    const fs::path json = dir_ / "subdivided.json";
    const Result result =
        run("bench --mesh " + mesh.string() +
            " --accel bvh --threads 1 --size 16 --frames 1 --subdivide 2 --json " + json.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    std::ostringstream text;
    text << std::ifstream(json).rdbuf();
    EXPECT_NE(text.str().find("\"triangles\": 48"), std::string::npos) << text.str();  // 3 x 16
    EXPECT_NE(text.str().find("mesh.off/s2"), std::string::npos) << text.str();
    EXPECT_EQ(run("bench --mesh " + mesh.string() + " --subdivide 5").exit_code, 2);
}

// --view adds the secondary sets of VIEWS.md, one record per view; their answers are checked across
// structures like the camera rays'. A floor under a floating triangle: some diffuse rays come back to the
// scene and some shadow rays are blocked.
TEST_F(Cli, BenchTimesTheDiffuseAndShadowViews) {
    const fs::path mesh = write("floor.off",
                                "OFF\n7 2 0\n0 0 0\n2 0 0\n2 2 0\n0 2 0\n"
                                "0.5 0.6 0.5\n1.5 0.6 0.5\n1 1.6 0.5\n4 0 1 2 3\n3 4 5 6\n");
    const fs::path json = dir_ / "views.json";
    const Result result = run("bench --mesh " + mesh.string() +
                              " --accel bvh,grid,bvh8_packet --threads 1 --size 32 --frames 1 --view "
                              "primary,diffuse,shadow --json " +
                              json.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    std::ostringstream text;
    text << std::ifstream(json).rdbuf();
    const std::string records = text.str();
    for (const char* view : {"\"view\": \"primary\"", "\"view\": \"diffuse\"", "\"view\": \"shadow\""}) {
        std::size_t count = 0;
        for (std::size_t at = records.find(view); at != std::string::npos; at = records.find(view, at + 1)) {
            ++count;
            const std::size_t field = records.find("\"hit_fraction\": ", at);
            ASSERT_NE(field, std::string::npos);
            EXPECT_GT(std::stod(records.substr(field + 16)), 0.01) << view;
        }
        EXPECT_EQ(count, 3u) << view << "\n" << records;  // 3 structures, 1 thread count
    }
    EXPECT_EQ(run("bench --mesh " + mesh.string() + " --view primary,glossy").exit_code, 2);
    // A triangle seen edge on: no camera ray hits it, so the secondary views have no rays and say so.
    const fs::path edge_on = write("edge.off", "OFF\n3 1 0\n0 0 0\n0 1 0\n0 0 1\n3 0 1 2\n");
    const Result empty = run("bench --mesh " + edge_on.string() +
                             " --accel bvh --threads 1 --size 32 --frames 1 --view diffuse");
    ASSERT_EQ(empty.exit_code, 0) << empty.output;
    EXPECT_NE(empty.output.find("the diffuse view has no rays"), std::string::npos) << empty.output;
}

// The default mode is Whitted's: a lit scene with a mirror ball reports its rays by kind; `.exr` writes
// OpenEXR (its magic number 76 2f 31 01).
// A lit, half-reflective ball over a checkered plane at 16x12: shadow and reflection rays.
const char* const kBallScene =
    "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 40\nhither 0.01\nresolution 16 12\n"
    "l 3 3 3\nf 0.8 0.8 0.8 0.5 0.5 20 0 1\ns 0 0 0 1\nplane 0 1 0 -1 checkered\n";

// --beside renders the same frame with a second structure and prints its Mrays/s; lancer's structures
// trace the same rays, so no ray-count line follows.
TEST_F(Cli, RenderBesideASecondStructure) {
    const fs::path scene = write("ball.nff", kBallScene);
    const fs::path png = dir_ / "beside.png";
    Result result = run("render " + scene.string() + " --accel bvh --beside grid -o " + png.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("beside: grid build"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("bvh at "), std::string::npos) << result.output;
    EXPECT_EQ(result.output.find("traced"), std::string::npos) << result.output;
    result = run("render " + scene.string() + " --beside nope -o " + png.string());
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_NE(result.output.find("--beside: unknown acceleration structure 'nope'"), std::string::npos)
        << result.output;
}

TEST_F(Cli, RenderDefaultsToWhittedAndWritesExr) {
    const fs::path scene = write("ball.nff", kBallScene);
    const fs::path exr = dir_ / "out.exr";
    const Result result = run("render " + scene.string() + " --spp 2 -o " + exr.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("16x12, 2 spp"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find("384 primary"), std::string::npos) << result.output;
    EXPECT_NE(result.output.find(" shadow, "), std::string::npos) << result.output;
    EXPECT_NE(result.output.find(" reflection, "), std::string::npos) << result.output;
    std::ifstream in(exr, std::ios::binary);
    unsigned char magic[4] = {};
    in.read(reinterpret_cast<char*>(magic), 4);
    EXPECT_EQ(magic[0], 0x76);
    EXPECT_EQ(magic[1], 0x2f);
    EXPECT_EQ(magic[2], 0x31);
    EXPECT_EQ(magic[3], 0x01);
}

// lancer convert writes the Plücker octree; rays and render read it back, with the same answers as a
// structure built on the mesh; a damaged file or a contradicting flag exits with 2.
TEST_F(Cli, ConvertedPluckerOctreeAnswersLikeTheMesh) {
    const fs::path mesh = write("mesh.off", kMesh);
    const fs::path octree = dir_ / "mesh.plo";
    Result result =
        run("convert " + mesh.string() + " --accel plucker --set plucker.leaf_size=1 -o " + octree.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("wrote"), std::string::npos) << result.output;

    std::vector<Ray> rays;
    for (int i = 0; i < 400; ++i) {
        const float x = -0.25f + 2.5f * static_cast<float>(i % 20) / 19.0f;
        const float y = -0.25f + 2.5f * static_cast<float>(i / 20) / 19.0f;
        rays.push_back({{x, y, 1.0f}, {0.01f * static_cast<float>(i % 3), 0.0f, -1.0f}, 0.0f, kInfinity});
    }
    const fs::path rays_file = dir_ / "rays.bin";
    std::ofstream(rays_file, std::ios::binary)
        .write(reinterpret_cast<const char*>(rays.data()),
               static_cast<std::streamsize>(rays.size() * sizeof(Ray)));
    auto hits_of = [&](const std::string& scene, const std::string& extra) {
        const fs::path hits_file = dir_ / "hits.bin";
        const Result traced =
            run("rays " + scene + " --rays " + rays_file.string() + " --hits " + hits_file.string() + extra);
        EXPECT_EQ(traced.exit_code, 0) << traced.output;
        std::vector<Hit> hits(rays.size());
        std::ifstream(hits_file, std::ios::binary)
            .read(reinterpret_cast<char*>(hits.data()),
                  static_cast<std::streamsize>(hits.size() * sizeof(Hit)));
        return hits;
    };
    const std::vector<Hit> from_mesh = hits_of(mesh.string(), " --accel brute");
    const std::vector<Hit> from_file = hits_of(octree.string(), "");
    int hit_count = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        ASSERT_EQ(from_file[i].prim, from_mesh[i].prim) << "ray " << i;
        ASSERT_EQ(from_file[i].t, from_mesh[i].t) << "ray " << i;
        hit_count += from_mesh[i].hit() ? 1 : 0;
    }
    EXPECT_GT(hit_count, 100);

    result = run("render " + octree.string() + " --size 32x32 -o " + (dir_ / "octree.png").string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("accel plucker"), std::string::npos) << result.output;

    result = run("stats " + octree.string() + " --accel bvh");
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("--accel must be plucker"), std::string::npos) << result.output;
    result = run("convert " + mesh.string() + " --accel bvh -o " + octree.string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("plucker octree only"), std::string::npos) << result.output;

    std::ifstream in(octree, std::ios::binary);
    std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const fs::path truncated = write("truncated.plo", data.substr(0, data.size() - 7));
    result = run("stats " + truncated.string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("truncated.plo: truncated"), std::string::npos) << result.output;
    const fs::path not_octree = write("mesh_as.plo", kMesh);
    result = run("render " + not_octree.string() + " -o " + (dir_ / "x.png").string());
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_NE(result.output.find("wrong magic"), std::string::npos) << result.output;
}

TEST_F(Cli, InfoCountsTrianglesAfterFanTriangulation) {
    const Result result = run("info " + write("mesh.off", kMesh).string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("triangles   3"), std::string::npos) << result.output;
}

// A glTF mesh that three nodes place is one object and three instances (support/instanced_gltf.hpp): the
// meshes placed once and the singular placement stay meshes.
TEST_F(Cli, InfoCountsObjectsInstancesAndTheInstancedTriangles) {
    const Result result = run("info " + test::write_instanced_gltf(dir_).string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    for (const char* line : {"meshes      3 ", "triangles   3\n", "objects     1 (1 triangles)",
                             "instances   3\n", "instanced   6 triangles"})
        EXPECT_NE(result.output.find(line), std::string::npos) << line << "\n" << result.output;
}

// A scene graph's mesh placed several times renders as instances, in every mode; --instances N places a
// mesh file's mesh N times; what an instanced scene cannot do is refused by name.
TEST_F(Cli, RendersInstancesInEveryMode) {
    const fs::path gltf = test::write_instanced_gltf(dir_), image = dir_ / "instanced.png";
    for (const char* mode : {"whitted", "flat", "normal", "depth", "heatmap"}) {
        const Result result =
            run("render " + gltf.string() + " --size 24x16 --mode " + mode + " -o " + image.string());
        ASSERT_EQ(result.exit_code, 0) << mode << "\n" << result.output;
        EXPECT_NE(result.output.find("1 objects placed by 3 instances, 6 instanced triangles"),
                  std::string::npos)
            << mode << "\n"
            << result.output;
        EXPECT_TRUE(fs::exists(image));
        fs::remove(image);
    }
    Result result = run("render " + write("mesh.off", kMesh).string() +
                        " --instances 20 --size 24x16 --mode flat -o " + image.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("1 objects placed by 20 instances, 60 instanced triangles"),
              std::string::npos)
        << result.output;
    result = run("render " + gltf.string() + " --beside bvh -o " + image.string());
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_NE(result.output.find("renders on the CPU alone"), std::string::npos) << result.output;
}

// `lancer stats` prints the figures each structure gives of itself, and its JSON holds the same keys: a tree
// its depth, a grid its cells and no depth.
TEST_F(Cli, StatsPrintsEachStructuresOwnFigures) {
    const fs::path mesh = write("mesh.off", kMesh), json = dir_ / "stats.json";
    Result result = run("stats " + mesh.string() + " --accel grid --json " + json.string());
    ASSERT_EQ(result.exit_code, 0) << result.output;
    EXPECT_NE(result.output.find("cells "), std::string::npos) << result.output;
    EXPECT_EQ(result.output.find("max_depth"), std::string::npos) << result.output;
    std::stringstream text;
    text << std::ifstream(json).rdbuf();
    EXPECT_NE(text.str().find("\"cells\": "), std::string::npos) << text.str();
    EXPECT_EQ(text.str().find("\"max_depth\""), std::string::npos) << text.str();

    result = run("stats " + mesh.string() + " --accel bvh");
    ASSERT_EQ(result.exit_code, 0) << result.output;
    for (const char* key : {"leaves ", "max_depth ", "sah_cost ", "sah_ratio "})
        EXPECT_NE(result.output.find(key), std::string::npos) << key << "\n" << result.output;
}

// `lancer info --options` prints the registry's structures and `--set` keys; the README holds the same
// tables. Every printed row must be in the README's block, and every `--set` row of that block must be
// printed (the structure rows may name Embree's, which a build without Embree does not print).
TEST_F(Cli, InfoOptionsListsTheRegistryAsTheReadmeDoes) {
    const Result result = run("info --options");
    ASSERT_EQ(result.exit_code, 0) << result.output;
    std::ostringstream text;
    text << std::ifstream(fs::path(LANCER_SOURCE_DIR) / "README.md").rdbuf();
    const std::string readme = text.str();
    const std::string begin = "<!-- lancer info --options -->\n",
                      end = "<!-- end of lancer info --options -->";
    const std::size_t first = readme.find(begin), last = readme.find(end);
    ASSERT_NE(first, std::string::npos);
    ASSERT_NE(last, std::string::npos);
    const std::string block = readme.substr(first + begin.size(), last - first - begin.size());
    const std::regex set_row(R"(^\| `[a-z]+\.[a-z_]+` \|.*)");
    std::istringstream printed(result.output);
    std::size_t set_rows = 0;
    for (std::string line; std::getline(printed, line);) {
        EXPECT_NE(block.find(line + "\n"), std::string::npos) << "not in the README: " << line;
        set_rows += std::regex_match(line, set_row) ? 1 : 0;
    }
    std::istringstream documented(block);
    for (std::string line; std::getline(documented, line);) {
        if (std::regex_match(line, set_row)) {
            EXPECT_NE(result.output.find(line + "\n"), std::string::npos) << "not printed: " << line;
        }
    }
    EXPECT_GE(set_rows, 19u);
    // A key that is not in the table is refused with the list of keys.
    const Result refused = run("stats " + write("mesh.off", kMesh).string() + " --set bvh.leafs=3");
    EXPECT_EQ(refused.exit_code, 2);
    EXPECT_NE(refused.output.find("KEY one of grid.density"), std::string::npos) << refused.output;
}

// Hostile inputs (issue 8): each exits with code 2 and names the file, the line and what was expected, before
// any large allocation (tests/scene/broken_input_test.cpp proves the last with an allocation probe).
TEST_F(Cli, HostileFilesExitWithTwoAndSayWhereAndWhat) {
    const fs::path broken = fs::path(LANCER_SOURCE_DIR) / "tests" / "scene" / "data" / "broken";
    const std::pair<const char*, const char*> cases[] = {
        {"huge_vertex_count.off", "huge_vertex_count.off:2: the file announces 1000000000000 vertices"},
        {"index_out_of_range.off", "index_out_of_range.off:15: face index 17 out of range [0, 12)"},
        {"truncated_in_faces.off",
         "truncated_in_faces.off:8: unexpected end of file: expected 3 faces, got 2"},
        {"truncated_in_vertices.ply", "truncated_in_vertices.ply:4: the file announces 6 vertex elements"},
        {"huge_polygon.nff", "huge_polygon.nff:1: the file announces 100000 polygon vertices"},
    };
    for (const auto& [name, expected] : cases) {
        for (const char* command : {"info", "stats"}) {
            const Result result = run(std::string(command) + " " + (broken / name).string());
            EXPECT_EQ(result.exit_code, 2) << command << " " << name << ": " << result.output;
            EXPECT_NE(result.output.find(expected), std::string::npos) << result.output;
        }
    }
}

// The outline of the square [0, side]^2 through every integer point of its edges, exactly convex in float.
std::vector<std::string> square_outline(int side) {
    std::vector<std::string> points;
    for (int i = 0; i < side; ++i)
        points.push_back(std::to_string(i) + " 0 0");
    for (int i = 0; i < side; ++i)
        points.push_back(std::to_string(side) + " " + std::to_string(i) + " 0");
    for (int i = side; i > 0; --i)
        points.push_back(std::to_string(i) + " " + std::to_string(side) + " 0");
    for (int i = side; i > 0; --i)
        points.push_back("0 " + std::to_string(i) + " 0");
    return points;
}

TEST_F(Cli, AHundredThousandVertexPolygonLoadsOrIsRefusedAtOnce) {
    const std::vector<std::string> square = square_outline(25'000);
    std::string off = "OFF\n100000 1 0\n", face = "100000", convex_nff = "p 100000\n",
                concave_nff = "p 100000\n";
    for (std::size_t i = 0; i < square.size(); ++i) {
        off += square[i] + "\n";
        face += " " + std::to_string(i);
        convex_nff += square[i] + "\n";
    }
    off += face + "\n";
    // A notch in every fourth vertex: concave, past the ear clipping bound (src/scene/polygon.hpp).
    for (std::size_t i = 0; i < 100'000; ++i) {
        const double angle = 2.0 * 3.14159265358979 * static_cast<double>(i) / 100'000.0;
        const double radius = i % 4 == 2 ? 0.9 : 1.0;
        concave_nff += std::to_string(radius * std::cos(angle)) + " " +
                       std::to_string(radius * std::sin(angle)) + " 0\n";
    }
    for (const auto& [name, text] : {std::pair{"polygon.off", off}, {"convex.nff", convex_nff}}) {
        const Result result = run("info " + write(name, text).string());
        EXPECT_EQ(result.exit_code, 0) << name << ": " << result.output;
        EXPECT_NE(result.output.find("triangles   99998"), std::string::npos)
            << name << ": " << result.output;
    }
    const Result concave = run("stats " + write("concave.nff", concave_nff).string());
    EXPECT_EQ(concave.exit_code, 2) << concave.output;
    EXPECT_NE(
        concave.output.find("concave.nff:1: expected a convex polygon or one of at most 2048 vertices, got a "
                            "concave one of 100000"),
        std::string::npos)
        << concave.output;
}

// A torus of 2 * 400 * 24 = 19200 triangles as an OFF file of about 700 kB: about 1 MB to load, several more
// to build.
std::string torus_off() {
    std::string vertices, faces;
    const int segments = 400, sides = 24;
    for (int i = 0; i < segments; ++i) {
        const double s = 2.0 * 3.14159265358979 * i / segments;
        for (int j = 0; j < sides; ++j) {
            const double a = 2.0 * 3.14159265358979 * j / sides;
            const double r = 1.0 + 0.3 * std::cos(a);
            vertices += std::to_string(r * std::cos(s)) + " " + std::to_string(r * std::sin(s)) + " " +
                        std::to_string(0.3 * std::sin(a)) + "\n";
            const int p = i * sides + j, q = (i + 1) % segments * sides + j;
            const int p1 = i * sides + (j + 1) % sides, q1 = (i + 1) % segments * sides + (j + 1) % sides;
            faces += "3 " + std::to_string(p) + " " + std::to_string(q) + " " + std::to_string(q1) + "\n";
            faces += "3 " + std::to_string(p) + " " + std::to_string(q1) + " " + std::to_string(p1) + "\n";
        }
    }
    return "OFF\n" + std::to_string(segments * sides) + " " + std::to_string(2 * segments * sides) + " 0\n" +
           vertices + faces;
}

TEST_F(Cli, MaxMemoryBoundsLoadingAndBuilding) {
    const fs::path scene = write("torus.off", torus_off());
    const fs::path plo = dir_ / "torus.plo";

    // Less than the program itself holds at start (CLI11, oneTBB): refused with the flag.
    Result result = run("stats " + scene.string() + " --max-memory 1K");
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_NE(result.output.find("--max-memory: 1K is less than the"), std::string::npos) << result.output;

    // Too little to load the 700 kB file: refused while loading, before the structure.
    result = run("stats " + scene.string() + " --accel octree --max-memory 512K");
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_NE(result.output.find("torus.off: needs more than --max-memory 512K while loading"),
              std::string::npos)
        << result.output;

    // Enough to load (under 2 MB), too little for the structures: each says which build.
    std::vector<std::string> accels = {"octree", "plucker", "bvh", "kdtree", "grid"};
    // Embree's allocations reach the count through its device memory monitor, when lancer has Embree.
    if (run("stats --help").output.find("embree") != std::string::npos) accels.push_back("embree");
    for (const std::string command : {"stats", "render", "rays", "convert"}) {
        for (const std::string& accel : accels) {
            if (command == "convert" && accel != "plucker") continue;
            // The default grid fits in 0.3 MB here: 16 times the density asks for 16^3 times the cells.
            std::string arguments = command + " " + scene.string() + " --accel " + accel +
                                    " --max-memory 3M" + (accel == "grid" ? " --set grid.density=16" : "");
            if (command == "render") arguments += " --size 8x8 -o " + (dir_ / "x.png").string();
            if (command == "rays")
                arguments +=
                    " --rays " + (dir_ / "none.bin").string() + " --hits " + (dir_ / "h.bin").string();
            if (command == "convert") arguments += " -o " + plo.string();
            result = run(arguments);
            EXPECT_EQ(result.exit_code, 2) << arguments << ": " << result.output;
            EXPECT_NE(result.output.find("needs more than --max-memory 3M while building " + accel),
                      std::string::npos)
                << arguments << ": " << result.output;
        }
    }

    result = run("stats " + scene.string() + " --accel octree --max-memory 2G");
    EXPECT_EQ(result.exit_code, 0) << result.output;
    result = run("bench --mesh " + scene.string() + " --accel bvh --size 16 --frames 1 --max-memory 2G");
    EXPECT_EQ(result.exit_code, 0) << result.output;
    result = run("bench --mesh " + scene.string() + " --accel bvh --size 16 --frames 1 --max-memory 512K");
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_NE(result.output.find("torus.off: needs more than --max-memory 512K while loading"),
              std::string::npos)
        << result.output;

    result = run("stats " + scene.string() + " --max-memory 12Q");
    EXPECT_EQ(result.exit_code, 2) << result.output;
    EXPECT_NE(result.output.find("expected a memory size such as 512M or 2G, got '12Q'"), std::string::npos)
        << result.output;
}

}  // namespace
}  // namespace lancer
