// OFF (Object File Format), as Ferreira & Mendoza 2011, section 5.2, and the usual readers know it:
//   OFF                      (COFF, NOFF and CNOFF too: their extra vertex columns are ignored)
//   nv nf [ne]               (may follow OFF on its line; ne is ignored)
//   x y z [...]              nv vertex lines, extra columns (colours, normals) ignored
//   n i0 ... i(n-1) [...]    nf face lines, n >= 3, 0-based indices, extra columns (colours) ignored
// '#' comments and blank lines may appear anywhere. Records are lines: a vertex or a face must sit on one.
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scene/loaders.hpp"
#include "scene/text_reader.hpp"

namespace lancer {

namespace {

// The fewest characters a record can take, its line break included ("0 0 0\n", "3 0 1 2\n", " 7"): the
// header counts are checked against these before anything is reserved.
constexpr std::size_t min_vertex_chars = 6;
constexpr std::size_t min_face_chars = 8;
constexpr std::size_t min_index_chars = 2;

bool is_off_magic(std::string_view token) {
    return token == "OFF" || token == "COFF" || token == "NOFF" || token == "CNOFF";
}

// The values of one record must sit on the line the record starts on.
void expect_on_line(TextReader& reader, const Token& start, std::uint64_t expected,
                    std::string_view plural_what, std::uint64_t got) {
    if (!reader.line_has_more_tokens()) {
        reader.fail(start.line, "expected " + count_message(expected, plural_what, got));
    }
}

}  // namespace

OffMesh read_off(const std::filesystem::path& file) {
    TextReader reader(file);
    const Token magic = reader.expect_token("'OFF'");
    if (!is_off_magic(magic.text)) reader.fail(magic.line, "expected 'OFF', got " + quote_token(magic.text));

    Token vertex_count_token, face_count_token;
    const std::uint64_t vertex_count = reader.read_count("a vertex count", &vertex_count_token);
    const std::uint64_t face_count = reader.read_count("a face count", &face_count_token);
    if (reader.line_has_more_tokens()) (void)reader.read_count("an edge count");
    reader.skip_rest_of_line();
    const std::size_t budget = reader.byte_budget();
    reader.check_fits(vertex_count, min_vertex_chars, budget, vertex_count_token, "vertices");
    reader.check_fits(face_count, min_face_chars, budget - vertex_count * min_vertex_chars, face_count_token,
                      "faces");
    // Unreachable below 24 GB of text, but the mesh's indices are 32-bit.
    constexpr std::uint64_t max_index = std::numeric_limits<std::uint32_t>::max();
    if (vertex_count > max_index || face_count > max_index) {
        reader.fail(vertex_count_token.line, "more vertices or faces than 32-bit indices can number");
    }

    OffMesh off;
    off.face_count = face_count;
    TriangleMesh& mesh = off.mesh;
    mesh.name = file.stem().string();
    mesh.positions.reserve(vertex_count);
    for (std::uint64_t vertex = 0; vertex < vertex_count; ++vertex) {
        const std::optional<Token> start = reader.peek();
        if (!start) reader.fail_at_end(count_message(vertex_count, "vertices", vertex));
        Vec3f position;
        for (int axis = 0; axis < 3; ++axis) {
            if (axis > 0)
                expect_on_line(reader, *start, 3, "vertex coordinates", static_cast<std::uint64_t>(axis));
            position[axis] = reader.read_float("3 vertex coordinates");
        }
        mesh.positions.push_back(position);
        reader.skip_rest_of_line();
    }

    // Exact for triangle meshes, the common case; polygons grow the arrays as they come.
    mesh.indices.reserve(3 * face_count);
    off.face_of_triangle.reserve(face_count);
    std::vector<std::uint32_t> polygon;
    for (std::uint64_t face = 0; face < face_count; ++face) {
        if (!reader.peek()) reader.fail_at_end(count_message(face_count, "faces", face));
        Token size_token;
        const std::uint64_t size = reader.read_count("a face vertex count", &size_token);
        if (size < 3) {
            reader.fail(size_token.line,
                        "expected a face of at least 3 vertices, got " + std::to_string(size));
        }
        reader.check_fits(size, min_index_chars, reader.byte_budget(), size_token, "face vertices");
        polygon.clear();
        for (std::uint64_t k = 0; k < size; ++k) {
            expect_on_line(reader, size_token, size, "vertex indices", k);
            const std::int64_t index = reader.read_integer("a vertex index");
            if (index < 0 || static_cast<std::uint64_t>(index) >= vertex_count) {
                reader.fail(size_token.line, "face index " + std::to_string(index) + " out of range [0, " +
                                                 std::to_string(vertex_count) + ")");
            }
            polygon.push_back(static_cast<std::uint32_t>(index));
        }
        reader.skip_rest_of_line();
        for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
            mesh.indices.insert(mesh.indices.end(), {polygon[0], polygon[k], polygon[k + 1]});
            off.face_of_triangle.push_back(static_cast<std::uint32_t>(face));
        }
    }
    if (const std::optional<Token> extra = reader.next()) {
        reader.fail(extra->line, "expected the end of the file after " + std::to_string(face_count) +
                                     " faces, got " + quote_token(extra->text));
    }
    return off;
}

Scene load_off(const std::filesystem::path& file) {
    Scene scene;
    scene.meshes.push_back(read_off(file).mesh);
    return scene;
}

}  // namespace lancer
