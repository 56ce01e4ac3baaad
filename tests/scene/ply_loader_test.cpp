// The PLY reader: ascii and binary of both byte orders, triangles in file order (faces fanned like OFF),
// normals, properties and elements it does not use, and damaged binary bodies.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene_test_util.hpp"

namespace lancer {
namespace {

using test::corpus;
using test::kOrderVertices;

void expect_triangle_indices(const TriangleMesh& mesh, std::size_t index, std::uint32_t a, std::uint32_t b,
                             std::uint32_t c) {
    ASSERT_LT(index, mesh.triangle_count());
    EXPECT_EQ(mesh.indices[3 * index], a) << "triangle " << index;
    EXPECT_EQ(mesh.indices[3 * index + 1], b) << "triangle " << index;
    EXPECT_EQ(mesh.indices[3 * index + 2], c) << "triangle " << index;
}

TEST(PlyLoader, AsciiFacesAreFannedInFileOrder) {
    const Scene scene = load_scene(corpus("good/order.ply"));
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    EXPECT_EQ(mesh.name, "order");
    EXPECT_EQ(mesh.positions, kOrderVertices);
    ASSERT_EQ(mesh.triangle_count(), 6u);
    expect_triangle_indices(mesh, 0, 0, 1, 2);
    expect_triangle_indices(mesh, 1, 1, 3, 2);
    expect_triangle_indices(mesh, 2, 3, 4, 5);  // the quad 3 4 5 0
    expect_triangle_indices(mesh, 3, 3, 5, 0);
    expect_triangle_indices(mesh, 4, 5, 0, 4);
    expect_triangle_indices(mesh, 5, 2, 4, 1);
    EXPECT_TRUE(mesh.normals.empty());
    EXPECT_EQ(scene.materials.size(), 1u);
    EXPECT_FALSE(scene.camera.has_value());
}

// A binary PLY of kOrderVertices, with a double-precision vertex colour property and an int8 face property
// the reader must step over, and the faces (i, i+1, i+2) mod 6 for i = 5 down to 0.
class BinaryPly {
  public:
    explicit BinaryPly(bool big_endian) : big_endian_(big_endian) {
        bytes_ = std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                 " 1.0\ncomment made by a test\nelement vertex 6\nproperty float x\nproperty float y\n"
                 "property float z\nproperty double quality\nelement face 6\n"
                 "property list uchar int vertex_indices\nproperty char flags\nend_header\n";
        for (const Vec3f& p : kOrderVertices)
            append(p.x), append(p.y), append(p.z), append(0.5);
        for (int i = 5; i >= 0; --i) {
            append(static_cast<std::uint8_t>(3));
            for (int k = 0; k < 3; ++k)
                append(static_cast<std::int32_t>((i + k) % 6));
            append(static_cast<std::int8_t>(-1));
        }
    }

    template <class T>
    void append(T value) {
        char raw[sizeof(T)];
        std::memcpy(raw, &value, sizeof(T));
        if (big_endian_ != (std::endian::native == std::endian::big)) std::reverse(raw, raw + sizeof(T));
        bytes_.append(raw, sizeof(T));
    }
    // Where vertex `v` starts, for tests that damage it.
    [[nodiscard]] std::size_t vertex_offset(std::size_t v) const {
        return bytes_.find("end_header\n") + 11 + v * 20;
    }

    std::string& bytes() { return bytes_; }

  private:
    bool big_endian_;
    std::string bytes_;
};

TEST(PlyLoader, BinaryBodiesOfBothByteOrdersGiveTheSameMesh) {
    test::ScratchDir dir;
    for (const bool big_endian : {false, true}) {
        BinaryPly ply(big_endian);
        const Scene scene = load_scene(dir.write(big_endian ? "big.ply" : "little.ply", ply.bytes()));
        ASSERT_EQ(scene.meshes.size(), 1u);
        const TriangleMesh& mesh = scene.meshes[0];
        EXPECT_EQ(mesh.positions, kOrderVertices);
        ASSERT_EQ(mesh.triangle_count(), 6u);
        for (std::uint32_t t = 0; t < 6; ++t) {
            const std::uint32_t i = 5 - t;
            expect_triangle_indices(mesh, t, i, (i + 1) % 6, (i + 2) % 6);
        }
    }
}

TEST(PlyLoader, ReadsNormalsAndSkipsOtherElements) {
    test::ScratchDir dir;
    const auto file =
        dir.write("normals.ply",
                  "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                  "property uchar red\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n"
                  "element face 1\nproperty list uchar uint vertex_index\nend_header\n"
                  "0 0 0 0 0 2 255\n1 0 0 0 0 1 0\n0 1 0 0 0 1 7\n"
                  "0 1\n"
                  "3 0 1 2\n");
    const Scene scene = load_scene(file);
    ASSERT_EQ(scene.meshes.size(), 1u);
    const TriangleMesh& mesh = scene.meshes[0];
    ASSERT_EQ(mesh.normals.size(), 3u);
    for (const Vec3f& normal : mesh.normals)
        EXPECT_EQ(normal, Vec3f(0.0f, 0.0f, 1.0f));
    expect_triangle_indices(mesh, 0, 0, 1, 2);
}

TEST(PlyLoader, PlyContentUnderAnotherNameIsStillReadHere) {
    test::ScratchDir dir;
    const auto file =
        dir.write("mesh.data",
                  "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                  "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 4\n");
    // The error of the hand-written reader, with its line number, proves which reader ran.
    test::expect_load_error(file, 13, "face index 4 out of range [0, 3)");
}

TEST(PlyLoader, DamagedBinaryBodiesAreLoadErrors) {
    test::ScratchDir dir;
    {
        BinaryPly ply(false);
        ply.bytes().resize(ply.bytes().size() - 3);  // into the last face's indices
        test::expect_load_error(dir.write("cut.ply", ply.bytes()), 0,
                                "unexpected end of file: the binary data stops in face 5 of 6");
    }
    {
        BinaryPly ply(false);
        ply.bytes().push_back('\0');
        test::expect_load_error(dir.write("longer.ply", ply.bytes()), 0, "got 1 more bytes");
    }
    {
        BinaryPly ply(false);
        const float nan = std::numeric_limits<float>::quiet_NaN();
        std::memcpy(ply.bytes().data() + ply.vertex_offset(2), &nan, sizeof nan);
        test::expect_load_error(dir.write("nan.ply", ply.bytes()), 0, "vertex 2: x is not a finite float");
    }
    {
        BinaryPly ply(false);
        const std::int32_t beyond = 6;
        // The first face's second index: after its uchar count and first int.
        const std::size_t first_face = ply.vertex_offset(6);
        std::memcpy(ply.bytes().data() + first_face + 5, &beyond, sizeof beyond);
        test::expect_load_error(dir.write("index.ply", ply.bytes()), 0, "face index 6 out of range [0, 6)");
    }
}

}  // namespace
}  // namespace lancer
