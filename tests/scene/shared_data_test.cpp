// The real data of shared/data (skipped when absent): the four Stanford meshes with the counts, bounds and
// triangle order of shared/data/README.md, and every SPD scene with its primitive counts and view.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene/polygon.hpp"
#include "scene_test_util.hpp"

namespace lancer {
namespace {

namespace fs = std::filesystem;

// The tests on shared/data skip, rather than fail, in a checkout without it.
class SharedData : public ::testing::Test {
  protected:
    void SetUp() override {
        if (test::shared_data().empty()) GTEST_SKIP() << "no shared/data in this checkout";
    }
};
class SharedMeshes : public SharedData {};
class SharedSpd : public SharedData {};

void expect_near(Vec3f actual, Vec3f expected, float tolerance, const std::string& what) {
    EXPECT_NEAR(actual.x, expected.x, tolerance) << what;
    EXPECT_NEAR(actual.y, expected.y, tolerance) << what;
    EXPECT_NEAR(actual.z, expected.z, tolerance) << what;
}

struct MeshFacts {
    const char* name;
    std::size_t triangles;
    Vec3f lo, hi;  // README section 1, six significant digits
};

const MeshFacts kMeshes[] = {
    {"bunny.obj", 69451, {-0.09469f, 0.032987f, -0.061874f}, {0.061009f, 0.187321f, 0.0588f}},
    {"armadillo.off", 99976, {-63.49726f, -54.22001f, -57.71452f}, {63.51741f, 97.08703f, 57.69647f}},
    {"dragon.ply", 871414, {-0.108324f, 0.0527295f, -0.0504143f}, {0.0965662f, 0.197173f, 0.0412075f}},
    {"dragon-res2.ply", 202520, {-0.108188f, 0.0527392f, -0.0503454f}, {0.0964062f, 0.197139f, 0.0411367f}},
};

TEST_F(SharedMeshes, CountsAndBoundsMatchTheReadme) {
    for (const MeshFacts& facts : kMeshes) {
        const Scene scene = load_scene(test::shared_data() / "meshes" / facts.name);
        ASSERT_EQ(scene.meshes.size(), 1u) << facts.name;
        EXPECT_EQ(scene.triangle_count(), facts.triangles) << facts.name;
        const Box3f bounds = scene.bounds();
        const float tolerance = 1e-5f * length(facts.hi - facts.lo);
        expect_near(bounds.lo, facts.lo, tolerance, facts.name);
        expect_near(bounds.hi, facts.hi, tolerance, facts.name);
        EXPECT_EQ(scene.materials.size(), 1u) << facts.name;
        EXPECT_FALSE(scene.camera.has_value()) << facts.name;
    }
}

// The positions and faces of a mesh file, read here independently of the loader.
struct ReferenceMesh {
    std::vector<Vec3f> vertices;
    std::vector<std::uint32_t> faces;  // three per triangle
};

// Compares triangle by triangle, in order, within `tolerance`: assimp's number parser (OBJ) is not correctly
// rounded, so its values may be one float step away from the stream's.
void expect_same_triangles(const TriangleMesh& mesh, const ReferenceMesh& reference, float tolerance,
                           const std::string& name) {
    ASSERT_EQ(mesh.triangle_count() * 3, reference.faces.size()) << name;
    std::size_t mismatches = 0;
    for (std::size_t t = 0; t < mesh.triangle_count() && mismatches < 10; ++t) {
        const Triangle triangle = mesh.triangle(t);
        const Vec3f corners[3] = {triangle.v0, triangle.v1, triangle.v2};
        for (int k = 0; k < 3; ++k) {
            const Vec3f expected = reference.vertices[reference.faces[3 * t + static_cast<std::size_t>(k)]];
            if (length(corners[k] - expected) > tolerance) {
                ++mismatches;
                ADD_FAILURE() << name << ": triangle " << t << " corner " << k << " differs";
            }
        }
    }
}

TEST_F(SharedMeshes, ObjTrianglesComeInFileOrder) {
    const fs::path file = test::shared_data() / "meshes/bunny.obj";
    ReferenceMesh reference;
    std::ifstream stream(file);
    std::string line;
    while (std::getline(stream, line)) {
        float x = 0, y = 0, z = 0;
        unsigned a = 0, b = 0, c = 0;
        if (std::sscanf(line.c_str(), "v %f %f %f", &x, &y, &z) == 3) reference.vertices.push_back({x, y, z});
        if (std::sscanf(line.c_str(), "f %u %u %u", &a, &b, &c) == 3)
            reference.faces.insert(reference.faces.end(), {a - 1, b - 1, c - 1});
    }
    const Scene scene = load_scene(file);
    expect_same_triangles(scene.meshes.at(0), reference, 1e-6f, "bunny.obj");
}

TEST_F(SharedMeshes, AsciiPlyTrianglesComeInFileOrder) {
    const fs::path file = test::shared_data() / "meshes/dragon-res2.ply";
    ReferenceMesh reference;
    std::ifstream stream(file);
    std::string word;
    std::size_t vertex_count = 0, face_count = 0;
    while (stream >> word && word != "end_header") {
        if (word == "element") {
            std::string name;
            std::size_t count = 0;
            stream >> name >> count;
            (name == "vertex" ? vertex_count : face_count) = count;
        }
    }
    std::string rest_of_line;
    for (std::size_t i = 0; i < vertex_count; ++i) {
        Vec3f p;
        stream >> p.x >> p.y >> p.z;
        std::getline(stream, rest_of_line);  // further vertex properties, if any
        reference.vertices.push_back(p);
    }
    for (std::size_t i = 0; i < face_count; ++i) {
        std::uint32_t n = 0, a = 0, b = 0, c = 0;
        stream >> n >> a >> b >> c;
        ASSERT_EQ(n, 3u);
        reference.faces.insert(reference.faces.end(), {a, b, c});
    }
    const Scene scene = load_scene(file);
    // Both parsers round correctly: the values must be the same floats.
    expect_same_triangles(scene.meshes.at(0), reference, 0.0f, "dragon-res2.ply");
}

TEST_F(SharedMeshes, BinaryPlyTrianglesComeInFileOrderBitForBit) {
    const fs::path file = test::shared_data() / "meshes/dragon.ply";
    std::ifstream stream(file, std::ios::binary);
    std::string line;
    while (std::getline(stream, line) && line != "end_header") {
    }
    // README: 437,645 float x y z, then 871,414 faces as uchar count and three int32.
    ReferenceMesh reference;
    reference.vertices.resize(437645);
    stream.read(reinterpret_cast<char*>(reference.vertices.data()),
                static_cast<std::streamsize>(reference.vertices.size() * sizeof(Vec3f)));
    for (std::size_t i = 0; i < 871414; ++i) {
        unsigned char n = 0;
        std::int32_t corners[3] = {};
        stream.read(reinterpret_cast<char*>(&n), 1);
        stream.read(reinterpret_cast<char*>(corners), sizeof corners);
        ASSERT_EQ(n, 3);
        for (const std::int32_t corner : corners)
            reference.faces.push_back(static_cast<std::uint32_t>(corner));
    }
    ASSERT_TRUE(stream);
    const Scene scene = load_scene(file);
    expect_same_triangles(scene.meshes.at(0), reference, 0.0f, "dragon.ply");
}

struct SpdFacts {
    const char* name;
    std::size_t spheres;
    // p and pp polygons give N - 2 triangles each; every c gives 48 (24 segments, two triangles each).
    std::size_t triangles;
    std::size_t lights;
    std::size_t materials;  // one per `f` line
    Vec3f from, at, up;
    float angle;
    int resolution;
    bool has_cones;  // README bounds of cones are conservative: ours must fit inside them
    Vec3f lo, hi;
};

constexpr std::size_t kPerCone = 48;
const Vec3f kZ{0, 0, 1};

// README section 2, "Counts by primitive type" and "Bounding boxes and views".
const SpdFacts kScenes[] = {
    {"balls.nff",
     7381,
     2,
     3,
     2,
     {2.1f, 1.3f, 1.7f},
     {0, 0, 0},
     kZ,
     45,
     512,
     false,
     {-12, -12, -0.5f},
     {12, 12, 0.830567f}},
    {"balls_s5.nff",
     66430,
     2,
     3,
     2,
     {2.1f, 1.3f, 1.7f},
     {0, 0, 0},
     kZ,
     45,
     512,
     false,
     {-12, -12, -0.5f},
     {12, 12, 0.833425f}},
    {"balls_s6.nff",
     597871,
     2,
     3,
     2,
     {2.1f, 1.3f, 1.7f},
     {0, 0, 0},
     kZ,
     45,
     512,
     false,
     {-12, -12, -0.5f},
     {12, 12, 0.834781f}},
    {"gears.nff",
     0,
     9217 * 2 + 128 * 142,
     5,
     65,
     {-1.1f, -2.1f, 2.6f},
     {0, 0, 0},
     kZ,
     45,
     512,
     false,
     {-2, -2, 0},
     {2, 2, 1}},
    {"mount.nff",
     4,
     8192,
     1,
     2,
     {-1.6f, 1.6f, 1.7f},
     {0, 0, 0},
     kZ,
     45,
     512,
     false,
     {-1.15961f, -1, -0.702953f},
     {1, 1.15961f, 1.37821f}},
    {"rings.nff",
     4200,
     4200 * kPerCone + 2,
     3,
     841,
     {-1, -2.61313f, 0.5f},
     {-1, -1.61313f, 0.5f},
     kZ,
     45,
     512,
     true,
     {-10.8389f, 1.65358f, -9.33895f},
     {8.83895f, 20.905f, 10.3389f}},
    {"teapot.nff",
     0,
     36 * 2 + 2256,
     2,
     3,
     {4.86f, 7.2f, 5.4f},
     {0, 0, 0},
     kZ,
     45,
     512,
     false,
     {-4, -4, 0},
     {4, 4, 3.15f}},
    {"teapot_s12.nff",
     0,
     144 * 2 + 9120,
     2,
     3,
     {4.86f, 7.2f, 5.4f},
     {0, 0, 0},
     kZ,
     45,
     512,
     false,
     {-4, -4, 0},
     {4, 4, 3.15f}},
    {"tetra.nff",
     0,
     4096,
     1,
     1,
     {1.02285f, -3.17715f, -2.17451f},
     {-0.004103f, -0.004103f, 0.216539f},
     {-0.816497f, -0.816497f, 0.816497f},
     45,
     512,
     false,
     {-1, -1, -1},
     {1, 1, 1}},
    {"tree.nff",
     4095,
     4095 * kPerCone + 2,
     7,
     2,
     {4.5f, 0.4f, 2},
     {0, 0, 1.5f},
     kZ,
     45,
     512,
     true,
     {-50, -50, -0.15f},
     {50, 50, 3.13749f}},
    {"lattice.nff",
     2197,
     6084 * kPerCone,
     6,
     8281,
     {0.541667f, 1, 0.958333f},
     {0.541667f, -1, -1.04167f},
     {0.2f, 1, 0},
     60,
     512,
     true,
     {-0.0208333f, -0.0208333f, -0.0208333f},
     {1.02083f, 1.02083f, 1.02083f}},
    {"shells.nff",
     5761,
     0,
     1,
     1,
     {-6, -60, 35},
     {0, 8, -15},
     kZ,
     45,
     512,
     false,
     {-27.3134f, -21.5798f, -50.706f},
     {17.0498f, 33.804f, -0.00350044f}},
    {"jacks.nff",
     6,
     3 * kPerCone,
     1,
     1,
     {0, 0, -8},
     {0, 0, 0},
     {0, 1, 0},
     25,
     256,
     true,
     {-0.854769f, -0.799519f, -0.760348f},
     {0.854769f, 0.799519f, 0.760348f}},
    {"sombrero.nff",
     0,
     1922,
     1,
     1,
     {0, 5, -8},
     {0, 0, 0},
     kZ,
     40,
     512,
     false,
     {-4, -3.60653f, -4},
     {4, -2, 4}},
};

TEST_F(SharedSpd, EverySceneLoadsWithTheReadmeCountsAndView) {
    for (const SpdFacts& facts : kScenes) {
        SCOPED_TRACE(facts.name);
        const Scene scene = load_scene(test::shared_data() / "spd" / facts.name);
        EXPECT_EQ(scene.spheres.size(), facts.spheres);
        EXPECT_EQ(scene.triangle_count(), facts.triangles);
        EXPECT_LE(scene.meshes.size(), 1u);
        EXPECT_EQ(scene.lights.size(), facts.lights);
        EXPECT_EQ(scene.materials.size(), facts.materials);
        // No SPD light has a colour: each gets the SPD's sqrt(N) / (2N).
        const auto count = static_cast<float>(facts.lights);
        for (const Light& light : scene.lights)
            EXPECT_EQ(light.color, Vec3f(std::sqrt(count) / (2.0f * count)));

        ASSERT_TRUE(scene.camera.has_value());
        EXPECT_EQ(scene.camera->eye, facts.from);
        EXPECT_EQ(scene.camera->look_at, facts.at);
        EXPECT_EQ(scene.camera->up, facts.up);
        EXPECT_EQ(scene.camera->vertical_fov_degrees, facts.angle);
        EXPECT_EQ(scene.camera->width, facts.resolution);
        EXPECT_EQ(scene.camera->height, facts.resolution);
        const bool jacks = std::string(facts.name) == "jacks.nff";
        EXPECT_EQ(scene.background, jacks ? Vec3f(0.2f, 0.05f, 0.2f) : Vec3f(0.078f, 0.361f, 0.753f));

        const Box3f bounds = scene.bounds();
        const float tolerance = 1e-5f * length(facts.hi - facts.lo);
        if (facts.has_cones) {
            EXPECT_TRUE((Box3f{facts.lo, facts.hi}.grown(tolerance).contains(bounds)));
        } else {
            expect_near(bounds.lo, facts.lo, tolerance, "lo");
            expect_near(bounds.hi, facts.hi, tolerance, "hi");
        }
    }
}

TEST_F(SharedSpd, TransmissiveMaterialsAreTwoSided) {
    const Scene scene = load_scene(test::shared_data() / "spd/mount.nff");
    // README: four glass spheres, T = 0.9, index 1.5.
    ASSERT_EQ(scene.spheres.size(), 4u);
    const Material& glass = scene.materials.at(scene.spheres[0].material);
    EXPECT_FLOAT_EQ(glass.kt, 0.9f);
    EXPECT_FLOAT_EQ(glass.ior, 1.5f);
    EXPECT_TRUE(glass.two_sided);
}

// The area of a planar polygon: its shoelace area on the plane of the dominant axis of `front`, divided by
// the cosine between that plane and the polygon's.
double outline_area(const std::vector<Vec3f>& polygon, Vec3f front) {
    const int axis = max_axis(abs(front));
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    double twice = 0.0;
    for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
        twice += static_cast<double>(polygon[j][u]) * polygon[i][v] -
                 static_cast<double>(polygon[i][u]) * polygon[j][v];
    }
    return std::fabs(twice) / 2.0 * length(front) / std::fabs(front[axis]);
}

// Each gear polygon, read here from the file: triangle areas must add up to the polygon's, and every
// triangle must face the polygon's front.
TEST_F(SharedSpd, GearFacesKeepTheirAreaAndWinding) {
    const fs::path file = test::shared_data() / "spd/gears.nff";
    const Scene scene = load_scene(file);
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];

    std::ifstream stream(file);
    std::string token;
    std::size_t triangle = 0, concave = 0;
    while (stream >> token) {
        if (token != "p") continue;  // the other entities of gears (b, v, l, f) hold no "p" token
        std::size_t count = 0;
        stream >> count;
        std::vector<Vec3f> polygon(count);
        for (Vec3f& p : polygon)
            stream >> p.x >> p.y >> p.z;
        const Vec3f front = polygon_normal(polygon);
        double area = 0.0;
        for (std::size_t k = 0; k + 2 < count; ++k, ++triangle) {
            const Vec3f normal = mesh.triangle(triangle).geometric_normal();
            EXPECT_GE(dot(normal, front), 0.0f) << "triangle " << triangle;
            area += length(normal) / 2.0;
        }
        const double expected = outline_area(polygon, front);
        EXPECT_NEAR(area, expected, 1e-4 * expected) << "polygon ending before triangle " << triangle;
        concave += count == 144 ? 1 : 0;
    }
    EXPECT_EQ(triangle, mesh.triangle_count());
    EXPECT_EQ(concave, 128u);
}

}  // namespace
}  // namespace lancer
