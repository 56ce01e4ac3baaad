// PLY (Turk's polygon file format), ascii and binary of either byte order, read here rather than through
// assimp: assimp 5.2 loops forever on a header cut before end_header, aborts the process on the faces of a
// truncated binary file once triangulated, and reads a truncated ascii body into more triangles than the
// file holds. The header's element counts are checked against the size of the body before anything is
// reserved, every index against the vertex count, and the body must end where the header says.
//
// Read: the element "vertex" (scalar properties x, y, z, and nx, ny, nz when all three are there) and the
// element "face" (the list vertex_indices, or vertex_index). Every other element and property is skipped.
// Faces are fanned (i0, ik, ik+1) like OFF faces, and numbered in file order.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lancer/load_scene.hpp"
#include "scene/loaders.hpp"
#include "scene/text_reader.hpp"

namespace lancer {

namespace {

enum class Encoding { ascii, little_endian, big_endian };
enum class Scalar { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

std::optional<Scalar> scalar_named(std::string_view name) {
    if (name == "char" || name == "int8") return Scalar::int8;
    if (name == "uchar" || name == "uint8") return Scalar::uint8;
    if (name == "short" || name == "int16") return Scalar::int16;
    if (name == "ushort" || name == "uint16") return Scalar::uint16;
    if (name == "int" || name == "int32") return Scalar::int32;
    if (name == "uint" || name == "uint32") return Scalar::uint32;
    if (name == "float" || name == "float32") return Scalar::float32;
    if (name == "double" || name == "float64") return Scalar::float64;
    return std::nullopt;
}

std::size_t size_of(Scalar type) {
    switch (type) {
        case Scalar::int8:
        case Scalar::uint8:
            return 1;
        case Scalar::int16:
        case Scalar::uint16:
            return 2;
        case Scalar::int32:
        case Scalar::uint32:
        case Scalar::float32:
            return 4;
        case Scalar::float64:
            return 8;
    }
    return 8;
}

bool is_integer(Scalar type) {
    return type != Scalar::float32 && type != Scalar::float64;
}

// What the reader does with a property's values.
enum class Role { ignored, x, y, z, nx, ny, nz, face_indices };

struct Property {
    std::string name;
    Scalar type = Scalar::float32;  // the items' type for a list
    std::optional<Scalar> list_count;
    Role role = Role::ignored;
};

struct Element {
    std::string name;
    std::uint64_t count = 0;
    Token count_token;
    std::vector<Property> properties;
};

constexpr std::string_view header_keywords =
    "a PLY header keyword (format, comment, element, property or end_header)";

// Raw values of a binary body, every type widened to double (exact for all of them).
class BinaryCursor {
  public:
    BinaryCursor(std::string_view bytes, bool big_endian) : bytes_(bytes), big_endian_(big_endian) {}

    [[nodiscard]] bool can_read(std::size_t size) const { return bytes_.size() - pos_ >= size; }
    [[nodiscard]] std::size_t remaining() const { return bytes_.size() - pos_; }

    // The caller checks can_read(size_of(type)) first.
    double read(Scalar type) {
        switch (type) {
            case Scalar::int8:
                return load<std::int8_t>();
            case Scalar::uint8:
                return load<std::uint8_t>();
            case Scalar::int16:
                return load<std::int16_t>();
            case Scalar::uint16:
                return load<std::uint16_t>();
            case Scalar::int32:
                return load<std::int32_t>();
            case Scalar::uint32:
                return load<std::uint32_t>();
            case Scalar::float32:
                return load<float>();
            case Scalar::float64:
                return load<double>();
        }
        return 0.0;
    }

  private:
    template <class T>
    T load() {
        unsigned char raw[sizeof(T)];
        std::memcpy(raw, bytes_.data() + pos_, sizeof(T));
        pos_ += sizeof(T);
        if (big_endian_ != (std::endian::native == std::endian::big)) {
            for (std::size_t i = 0; i < sizeof(T) / 2; ++i)
                std::swap(raw[i], raw[sizeof(T) - 1 - i]);
        }
        T value;
        std::memcpy(&value, raw, sizeof(T));
        return value;
    }

    std::string_view bytes_;
    std::size_t pos_ = 0;
    bool big_endian_;
};

class PlyReader {
  public:
    explicit PlyReader(const std::filesystem::path& file) : file_(file), reader_(file) {}

    TriangleMesh read() {
        read_header();
        mesh_.name = file_.stem().string();
        if (encoding_ == Encoding::ascii) {
            read_ascii_body();
        } else {
            read_binary_body(reader_.bytes_after_line());
        }
        if (!normals_usable_) mesh_.normals.clear();
        return std::move(mesh_);
    }

  private:
    void read_header() {
        const Token magic = reader_.expect_token("'ply'");
        if (magic.text != "ply") reader_.fail(magic.line, "expected 'ply', got " + quote_token(magic.text));
        std::optional<Encoding> encoding;
        while (true) {
            const Token keyword = reader_.expect_token(header_keywords);
            if (keyword.text == "end_header") break;
            if (keyword.text == "format") {
                const Token format =
                    reader_.expect_token("a format (ascii, binary_little_endian or binary_big_endian)");
                if (format.text == "ascii") {
                    encoding = Encoding::ascii;
                } else if (format.text == "binary_little_endian") {
                    encoding = Encoding::little_endian;
                } else if (format.text == "binary_big_endian") {
                    encoding = Encoding::big_endian;
                } else {
                    reader_.fail(
                        format.line,
                        "expected a format (ascii, binary_little_endian or binary_big_endian), got " +
                            quote_token(format.text));
                }
                reader_.skip_rest_of_line();  // the version
            } else if (keyword.text == "comment" || keyword.text == "obj_info") {
                reader_.skip_rest_of_line();
            } else if (keyword.text == "element") {
                Element element;
                element.name = std::string(reader_.expect_token("an element name").text);
                element.count = reader_.read_count("an element count", &element.count_token);
                elements_.push_back(std::move(element));
            } else if (keyword.text == "property") {
                if (elements_.empty()) reader_.fail(keyword.line, "a property before any element");
                read_property(elements_.back());
            } else {
                reader_.fail(keyword.line, "expected " + std::string(header_keywords) + ", got " +
                                               quote_token(keyword.text));
            }
        }
        if (!encoding) reader_.fail(magic.line, "the header has no format line");
        encoding_ = *encoding;
        assign_roles();
    }

    Scalar read_scalar_type(std::string_view what) {
        const Token token = reader_.expect_token(what);
        const std::optional<Scalar> type = scalar_named(token.text);
        if (!type)
            reader_.fail(token.line, "expected " + std::string(what) + ", got " + quote_token(token.text));
        return *type;
    }

    void read_property(Element& element) {
        Property property;
        const std::optional<Token> list = reader_.peek();
        if (list && list->text == "list") {
            (void)reader_.next();
            property.list_count = read_scalar_type("a list count type");
            if (!is_integer(*property.list_count))
                reader_.fail(list->line, "a list count type must be an integer type");
        }
        property.type = read_scalar_type("a property type");
        property.name = std::string(reader_.expect_token("a property name").text);
        element.properties.push_back(std::move(property));
    }

    void assign_roles() {
        for (std::size_t e = 0; e < elements_.size(); ++e) {
            Element& element = elements_[e];
            if (element.name == "vertex" && !vertex_element_) {
                vertex_element_ = e;
                for (Property& property : element.properties) {
                    if (property.list_count) continue;
                    const std::string_view name = property.name;
                    property.role = name == "x"    ? Role::x
                                    : name == "y"  ? Role::y
                                    : name == "z"  ? Role::z
                                    : name == "nx" ? Role::nx
                                    : name == "ny" ? Role::ny
                                    : name == "nz" ? Role::nz
                                                   : Role::ignored;
                }
                require_roles(element, {Role::x, Role::y, Role::z}, "x, y and z");
                has_normals_ = count_role(element, Role::nx) == 1 && count_role(element, Role::ny) == 1 &&
                               count_role(element, Role::nz) == 1;
                if (!has_normals_) {
                    for (Property& property : element.properties) {
                        if (property.role == Role::nx || property.role == Role::ny ||
                            property.role == Role::nz)
                            property.role = Role::ignored;
                    }
                }
            } else if (element.name == "face" && !face_element_) {
                face_element_ = e;
                for (Property& property : element.properties) {
                    if (property.name == "vertex_indices" || property.name == "vertex_index") {
                        if (!property.list_count || !is_integer(property.type)) {
                            reader_.fail(element.count_token.line, "the face property " + property.name +
                                                                       " must be a list of integers");
                        }
                        property.role = Role::face_indices;
                    }
                }
                require_roles(element, {Role::face_indices}, "vertex_indices");
            }
        }
        vertex_count_ = vertex_element_ ? elements_[*vertex_element_].count : 0;
        if (vertex_count_ > std::numeric_limits<std::uint32_t>::max()) {
            reader_.fail(elements_[*vertex_element_].count_token.line,
                         "more vertices than 32-bit indices can number");
        }
    }

    static int count_role(const Element& element, Role role) {
        int count = 0;
        for (const Property& property : element.properties)
            count += property.role == role ? 1 : 0;
        return count;
    }

    void require_roles(const Element& element, std::initializer_list<Role> roles, std::string_view names) {
        for (const Role role : roles) {
            if (count_role(element, role) != 1) {
                reader_.fail(element.count_token.line, "the element " + element.name +
                                                           " needs exactly one property each of " +
                                                           std::string(names));
            }
        }
    }

    // The fewest bytes one instance of `element` takes: a token and a separator per value in ascii, the
    // scalars and list counts in binary. Never zero, so that the count check bounds every loop.
    std::size_t min_instance_bytes(const Element& element) const {
        std::size_t bytes = 0;
        for (const Property& property : element.properties) {
            if (encoding_ == Encoding::ascii) {
                bytes += 2;
            } else {
                bytes += size_of(property.list_count ? *property.list_count : property.type);
            }
        }
        return std::max<std::size_t>(bytes, 1);
    }

    void check_counts(std::size_t budget) {
        for (const Element& element : elements_) {
            const std::size_t min_bytes = min_instance_bytes(element);
            reader_.check_fits(element.count, min_bytes, budget, element.count_token,
                               element.name + " elements");
            budget -= static_cast<std::size_t>(element.count) * min_bytes;
        }
        mesh_.reserve(vertex_element_ ? vertex_count_ : 0,
                      face_element_ ? elements_[*face_element_].count : 0);
        if (vertex_element_ && has_normals_) mesh_.normals.reserve(vertex_count_);
    }

    // One value of a vertex: positions must be finite; normals too, and a zero one makes all unusable.
    void store_vertex_value(Role role, double value, Vec3f& position, Vec3f& normal, std::uint64_t vertex) {
        const auto single = static_cast<float>(value);
        if (!std::isfinite(single)) {
            fail_value("vertex " + std::to_string(vertex) + ": " + std::string(role_name(role)) +
                       " is not a finite float");
        }
        switch (role) {
            case Role::x:
                position.x = single;
                break;
            case Role::y:
                position.y = single;
                break;
            case Role::z:
                position.z = single;
                break;
            case Role::nx:
                normal.x = single;
                break;
            case Role::ny:
                normal.y = single;
                break;
            case Role::nz:
                normal.z = single;
                break;
            case Role::ignored:
            case Role::face_indices:
                break;
        }
    }

    static std::string_view role_name(Role role) {
        switch (role) {
            case Role::x:
                return "x";
            case Role::y:
                return "y";
            case Role::z:
                return "z";
            case Role::nx:
                return "nx";
            case Role::ny:
                return "ny";
            case Role::nz:
                return "nz";
            case Role::ignored:
            case Role::face_indices:
                break;
        }
        return "value";
    }

    void finish_vertex(Vec3f position, Vec3f normal) {
        mesh_.positions.push_back(position);
        if (!has_normals_) return;
        const float norm = length(normal);
        if (norm > 0.0f && std::isfinite(norm)) {
            mesh_.normals.push_back(normal / norm);
        } else {
            normals_usable_ = false;
            mesh_.normals.push_back(normal);
        }
    }

    // Fans the face in polygon_ after checking its size and indices.
    void finish_face(std::uint64_t face, std::size_t line) {
        if (polygon_.size() < 3) {
            reader_.fail(line, "face " + std::to_string(face) + ": expected at least 3 vertices, got " +
                                   std::to_string(polygon_.size()));
        }
        for (std::size_t k = 1; k + 1 < polygon_.size(); ++k) {
            mesh_.indices.insert(mesh_.indices.end(), {polygon_[0], polygon_[k], polygon_[k + 1]});
        }
    }

    std::uint32_t checked_index(double value, std::size_t line) {
        if (!(value >= 0.0 && value < static_cast<double>(vertex_count_))) {
            reader_.fail(line, "face index " + std::to_string(static_cast<long long>(value)) +
                                   " out of range [0, " + std::to_string(vertex_count_) + ")");
        }
        return static_cast<std::uint32_t>(value);
    }

    [[noreturn]] void fail_value(const std::string& message) { throw LoadError(file_, 0, message); }

    void read_ascii_body() {
        check_counts(reader_.byte_budget());
        for (std::size_t e = 0; e < elements_.size(); ++e) {
            const Element& element = elements_[e];
            const bool vertices = vertex_element_ == e, faces = face_element_ == e;
            for (std::uint64_t i = 0; i < element.count; ++i) {
                const std::optional<Token> start = reader_.peek();
                if (!start) {
                    reader_.fail_at_end(count_message(element.count, element.name + " elements", i));
                }
                Vec3f position, normal;
                polygon_.clear();
                for (const Property& property : element.properties) {
                    if (property.list_count) {
                        Token count_token;
                        const std::uint64_t count = reader_.read_count("a list length", &count_token);
                        reader_.check_fits(count, 2, reader_.byte_budget(), count_token, "list items");
                        for (std::uint64_t k = 0; k < count; ++k) {
                            if (property.role != Role::face_indices) {
                                (void)reader_.expect_token("a list item");
                                continue;
                            }
                            Token index_token;
                            const std::int64_t index = reader_.read_integer("a vertex index", &index_token);
                            polygon_.push_back(checked_index(static_cast<double>(index), index_token.line));
                        }
                    } else if (property.role == Role::ignored) {
                        (void)reader_.expect_token("a property value");
                    } else {
                        const float value = reader_.read_float("a vertex coordinate or normal");
                        store_vertex_value(property.role, value, position, normal, i);
                    }
                }
                if (vertices) finish_vertex(position, normal);
                if (faces) finish_face(i, start->line);
            }
        }
        if (const std::optional<Token> extra = reader_.next()) {
            reader_.fail(extra->line, "expected the end of the file after the last element, got " +
                                          quote_token(extra->text));
        }
    }

    void read_binary_body(std::string_view bytes) {
        check_counts(bytes.size());
        BinaryCursor cursor(bytes, encoding_ == Encoding::big_endian);
        for (std::size_t e = 0; e < elements_.size(); ++e) {
            const Element& element = elements_[e];
            const bool vertices = vertex_element_ == e, faces = face_element_ == e;
            for (std::uint64_t i = 0; i < element.count; ++i) {
                const auto cut_short = [&] {
                    fail_value("unexpected end of file: the binary data stops in " + element.name + " " +
                               std::to_string(i) + " of " + std::to_string(element.count));
                };
                Vec3f position, normal;
                polygon_.clear();
                for (const Property& property : element.properties) {
                    if (property.list_count) {
                        if (!cursor.can_read(size_of(*property.list_count))) cut_short();
                        const double count = cursor.read(*property.list_count);
                        if (count < 0.0) {
                            fail_value(element.name + " " + std::to_string(i) + ": a negative list length");
                        }
                        if (static_cast<std::size_t>(count) > cursor.remaining() / size_of(property.type)) {
                            cut_short();
                        }
                        for (std::size_t k = 0; k < static_cast<std::size_t>(count); ++k) {
                            const double item = cursor.read(property.type);
                            if (property.role == Role::face_indices)
                                polygon_.push_back(checked_index(item, 0));
                        }
                    } else {
                        if (!cursor.can_read(size_of(property.type))) cut_short();
                        const double value = cursor.read(property.type);
                        if (property.role != Role::ignored) {
                            store_vertex_value(property.role, value, position, normal, i);
                        }
                    }
                }
                if (vertices) finish_vertex(position, normal);
                if (faces) finish_face(i, 0);
            }
        }
        if (cursor.remaining() > 0) {
            fail_value("expected the end of the file after the last element, got " +
                       std::to_string(cursor.remaining()) + " more bytes");
        }
    }

    std::filesystem::path file_;
    TextReader reader_;
    Encoding encoding_ = Encoding::ascii;
    std::vector<Element> elements_;
    std::optional<std::size_t> vertex_element_, face_element_;
    std::uint64_t vertex_count_ = 0;
    bool has_normals_ = false;
    bool normals_usable_ = true;
    TriangleMesh mesh_;
    std::vector<std::uint32_t> polygon_;  // scratch: the indices of the face being read
};

}  // namespace

Scene load_ply(const std::filesystem::path& file) {
    Scene scene;
    scene.meshes.push_back(PlyReader(file).read());
    return scene;
}

}  // namespace lancer
