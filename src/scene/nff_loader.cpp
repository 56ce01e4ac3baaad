// NFF, Eric Haines' Neutral File Format as the Standard Procedural Databases write it (shared/data/README.md
// section 3), read as a stream of whitespace-separated tokens since SPD lets an entity run over several
// lines. Polygons and cones become triangles of one mesh in file order, spheres stay spheres; two lancer
// extensions, `plane` and `ambient`. Every keyword, the tessellation and the mesh grouping:
// docs/formats.md, "NFF".
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "scene/loaders.hpp"
#include "scene/polygon.hpp"
#include "scene/text_reader.hpp"

namespace lancer {

namespace {

// Quads around a cone: the largest SPD cones cover a few dozen pixels of a 512 x 512 image, where 24
// facets with smooth normals read as round.
constexpr std::uint32_t cone_segments = 24;
// The fewest characters of a polygon vertex ("0 0 0\n") and of a patch vertex ("0 0 0 0 0 1\n").
constexpr std::size_t min_polygon_vertex_chars = 6;
constexpr std::size_t min_patch_vertex_chars = 12;
constexpr std::string_view keyword_list = "a keyword (v, b, l, f, c, s, p, pp, plane or ambient)";

Vec3f normalized_or_zero(Vec3f v) {
    const float norm = length(v);
    return norm > 0.0f && std::isfinite(norm) ? v / norm : Vec3f{};
}

class NffReader {
  public:
    explicit NffReader(const std::filesystem::path& file) : reader_(file) {
        mesh_.name = file.stem().string();
    }

    Scene read() {
        // No entity at all is a file cut to nothing, not a scene.
        if (!reader_.peek()) reader_.fail_at_end(keyword_list);
        while (const std::optional<Token> token = reader_.next()) {
            const std::string_view keyword = token->text;
            if (keyword == "s") {
                read_sphere();
            } else if (keyword == "p") {
                read_polygon(false);
            } else if (keyword == "pp") {
                read_polygon(true);
            } else if (keyword == "f") {
                read_material();
            } else if (keyword == "c") {
                read_cone();
            } else if (keyword == "l") {
                read_light();
            } else if (keyword == "b") {
                scene_.background = reader_.read_vec3("a background colour r g b");
            } else if (keyword == "v") {
                read_view(*token);
            } else if (keyword == "plane") {
                read_plane(*token);
            } else if (keyword == "ambient") {
                scene_.ambient = reader_.read_vec3("an ambient colour r g b");
                ambient_given_ = true;
            } else {
                reader_.fail(token->line,
                             "expected " + std::string(keyword_list) + ", got " + quote_token(keyword));
            }
        }
        if (!has_shading_normals_) mesh_.normals.clear();
        if (mesh_.triangle_count() > 0) scene_.meshes.push_back(std::move(mesh_));
        apply_spd_intensities();
        return std::move(scene_);
    }

  private:
    // v, then from, at, up, angle, hither and resolution in this order (NFF.TXT). hither is read and
    // dropped: the camera has no near plane.
    void read_view(const Token& keyword) {
        Camera camera;
        reader_.expect_keyword("from");
        camera.eye = reader_.read_vec3("an eye position x y z after 'from'");
        reader_.expect_keyword("at");
        camera.look_at = reader_.read_vec3("a look-at point x y z after 'at'");
        reader_.expect_keyword("up");
        camera.up = reader_.read_vec3("an up vector x y z after 'up'");
        reader_.expect_keyword("angle");
        Token angle;
        camera.vertical_fov_degrees = reader_.read_float("a field of view in degrees after 'angle'", &angle);
        if (!(camera.vertical_fov_degrees > 0.0f && camera.vertical_fov_degrees < 180.0f)) {
            reader_.fail(angle.line, "expected a field of view between 0 and 180 degrees, got " +
                                         quote_token(angle.text));
        }
        reader_.expect_keyword("hither");
        (void)reader_.read_float("a near distance after 'hither'");
        reader_.expect_keyword("resolution");
        camera.width = reader_.read_image_side("an image width after 'resolution'");
        camera.height = reader_.read_image_side("an image height after 'resolution'");
        // The camera frame is normalize(cross(at - from, up)): it needs a direction and an up off its axis.
        if (cross(camera.look_at - camera.eye, camera.up) == Vec3f{}) {
            reader_.fail(keyword.line, "the view has no direction, or an up vector along it");
        }
        scene_.camera = camera;
    }

    // l x y z [r g b]: the SPD intensity (apply_spd_intensities) unless a colour follows.
    void read_light() {
        Light light;
        light.position = reader_.read_vec3("a light position x y z");
        const bool colored = reader_.next_is_number();
        if (colored) light.color = reader_.read_vec3("a light colour r g b");
        light_colored_.push_back(colored);
        scene_.lights.push_back(light);
    }

    // The SPD Readme: "each light and the ambient term" get the relative intensity sqrt(N) / (2N) for N
    // lights, so that a surface facing every light is not washed out. With no light the ambient default
    // stays.
    void apply_spd_intensities() {
        if (scene_.lights.empty()) return;
        const auto count = static_cast<float>(scene_.lights.size());
        const float intensity = std::sqrt(count) / (2.0f * count);
        for (std::size_t i = 0; i < scene_.lights.size(); ++i) {
            if (!light_colored_[i]) scene_.lights[i].color = Vec3f(intensity);
        }
        if (!ambient_given_) scene_.ambient = Vec3f(intensity);
    }

    // plane nx ny nz d [checkered] (a lancer extension): x . n = d, n normalised along with d.
    void read_plane(const Token& keyword) {
        Plane plane;
        const Vec3f normal = reader_.read_vec3("a plane normal nx ny nz");
        const float offset = reader_.read_float("a plane offset d");
        const float norm = length(normal);
        if (!(norm > 0.0f && std::isfinite(norm))) {
            reader_.fail(keyword.line, "a plane needs a non-zero normal");
        }
        plane.normal = normal / norm;
        plane.offset = offset / norm;
        // A tiny normal divides a finite offset beyond the float range (fuzz/nff_fuzz.cpp).
        if (!std::isfinite(plane.offset))
            reader_.fail(keyword.line, "a plane offset d / |n| beyond the float range");
        if (const std::optional<Token> flag = reader_.peek(); flag && flag->text == "checkered") {
            (void)reader_.next();
            plane.checkered = true;
        }
        plane.material = current_material();
        scene_.planes.push_back(plane);
    }

    // f r g b Kd Ks Shine T ior: one material per line, for every primitive until the next one.
    void read_material() {
        Material material;
        material.color = reader_.read_vec3("a material colour r g b");
        material.kd = reader_.read_float("a diffuse weight Kd");
        material.ks = reader_.read_float("a specular weight Ks");
        material.shininess = reader_.read_float("a Phong exponent Shine");
        material.kt = reader_.read_float("a transmittance T");
        material.ior = reader_.read_float("an index of refraction");
        // NFF: transmissive surfaces have two sides, so that refracted rays see their back faces.
        material.two_sided = material.kt > 0.0f;
        current_material_ = static_cast<std::uint32_t>(scene_.materials.size());
        scene_.materials.push_back(material);
    }

    // Primitives before the first `f` get a default material.
    std::uint32_t current_material() {
        if (!current_material_) {
            current_material_ = static_cast<std::uint32_t>(scene_.materials.size());
            scene_.materials.emplace_back();
        }
        return *current_material_;
    }

    void read_sphere() {
        Sphere sphere;
        sphere.center = reader_.read_vec3("a sphere centre x y z");
        Token radius;
        sphere.radius = reader_.read_float("a sphere radius", &radius);
        if (!(sphere.radius > 0.0f)) {
            reader_.fail(radius.line, "expected a positive sphere radius, got " + quote_token(radius.text));
        }
        sphere.material = current_material();
        scene_.spheres.push_back(sphere);
    }

    // The mesh indexes its vertices with 32 bits.
    std::uint32_t reserve_vertices(std::size_t count, const Token& where) {
        const std::size_t first = mesh_.positions.size();
        if (count > std::numeric_limits<std::uint32_t>::max() - first) {
            reader_.fail(where.line, "more vertices than 32-bit indices can number");
        }
        return static_cast<std::uint32_t>(first);
    }

    void add_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t material) {
        mesh_.indices.insert(mesh_.indices.end(), {a, b, c});
        mesh_.material_ids.push_back(material);
    }

    // p N then N vertices x y z; pp N then N vertices x y z nx ny nz.
    void read_polygon(bool with_normals) {
        Token count_token;
        const std::uint64_t count = reader_.read_count("a polygon vertex count", &count_token);
        if (count < 3) {
            reader_.fail(count_token.line,
                         "expected a polygon of at least 3 vertices, got " + std::to_string(count));
        }
        reader_.check_fits(count, with_normals ? min_patch_vertex_chars : min_polygon_vertex_chars,
                           reader_.byte_budget(), count_token, "polygon vertices");
        polygon_.clear();
        polygon_normals_.clear();
        for (std::uint64_t i = 0; i < count; ++i) {
            if (!reader_.peek()) {
                reader_.fail_at_end(count_message(count, "polygon vertices", i));
            }
            polygon_.push_back(reader_.read_vec3("a polygon vertex x y z"));
            if (with_normals) polygon_normals_.push_back(reader_.read_vec3("a vertex normal nx ny nz"));
        }

        const std::uint32_t first = reserve_vertices(polygon_.size(), count_token);
        // A polygon without area by NFF's rule and by Newell's is invalid input; its vertices still need a
        // unit normal.
        Vec3f face_normal = normalized_or_zero(polygon_normal(polygon_));
        if (face_normal == Vec3f{}) face_normal = {0.0f, 0.0f, 1.0f};
        mesh_.positions.insert(mesh_.positions.end(), polygon_.begin(), polygon_.end());
        for (std::size_t i = 0; i < polygon_.size(); ++i) {
            // A patch normal of zero length cannot shade; the face normal stands in for it.
            const Vec3f normal = with_normals ? normalized_or_zero(polygon_normals_[i]) : Vec3f{};
            mesh_.normals.push_back(normal != Vec3f{} ? normal : face_normal);
        }
        has_shading_normals_ = has_shading_normals_ || with_normals;

        const std::uint32_t material = current_material();
        triangles_.clear();
        if (!triangulate_polygon(polygon_, triangles_)) {
            reader_.fail(count_token.line, "expected a convex polygon or one of at most " +
                                               std::to_string(kMaxEarClippedVertices) +
                                               " vertices, got a concave one of " + std::to_string(count));
        }
        for (std::size_t i = 0; i < triangles_.size(); i += 3) {
            add_triangle(first + triangles_[i], first + triangles_[i + 1], first + triangles_[i + 2],
                         material);
        }
    }

    // c bx by bz br ax ay az ar: the side of a cone from the base circle to the apex circle.
    void read_cone() {
        const Vec3f base = reader_.read_vec3("a cone base centre x y z");
        Token base_token;
        const float base_radius = reader_.read_float("a cone base radius", &base_token);
        const Vec3f apex = reader_.read_vec3("a cone apex centre x y z");
        const float apex_radius = reader_.read_float("a cone apex radius");
        const float height = length(apex - base);
        if (!(height > 0.0f && std::isfinite(height))) {
            reader_.fail(base_token.line, "a cone needs distinct base and apex centres at a finite distance");
        }
        const bool outside = base_radius >= 0.0f && apex_radius >= 0.0f;
        const bool inside = base_radius <= 0.0f && apex_radius <= 0.0f;
        if (outside == inside) {
            // Both radii zero, or of opposite signs.
            reader_.fail(base_token.line, "expected cone radii of one sign, not both zero, got " +
                                              std::to_string(base_radius) + " and " +
                                              std::to_string(apex_radius));
        }
        tessellate_cone(base, std::fabs(base_radius), apex, std::fabs(apex_radius), inside, base_token);
    }

    // Two rings of cone_segments vertices on the true surface (an inscribed polygon), joined by two
    // triangles per segment that face outwards (inwards when `inside`, NFF's negative radii). Normals are
    // the smooth cone normals. A ring of radius zero is the tip: its flat triangles are left out.
    void tessellate_cone(Vec3f base, float base_radius, Vec3f apex, float apex_radius, bool inside,
                         const Token& where) {
        const Vec3f axis = apex - base;
        const float height = length(axis);
        const Vec3f w = axis / height;
        // (u, v, w) right-handed: u x v = w, so the angle grows counter-clockwise seen from the apex.
        const Vec3f helper = std::fabs(w.x) < 0.5f ? Vec3f{1.0f, 0.0f, 0.0f} : Vec3f{0.0f, 1.0f, 0.0f};
        const Vec3f u = normalize(cross(helper, w));
        const Vec3f v = cross(w, u);

        const std::uint32_t first = reserve_vertices(2 * cone_segments, where);
        for (int ring = 0; ring < 2; ++ring) {
            const Vec3f center = ring == 0 ? base : apex;
            const float radius = ring == 0 ? base_radius : apex_radius;
            for (std::uint32_t i = 0; i < cone_segments; ++i) {
                const float angle = 2.0f * std::numbers::pi_v<float> * static_cast<float>(i) /
                                    static_cast<float>(cone_segments);
                const Vec3f radial = std::cos(angle) * u + std::sin(angle) * v;
                mesh_.positions.push_back(center + radius * radial);
                // Perpendicular to the generator (apex_radius - base_radius) radial + height w.
                const Vec3f normal = normalize(height * radial + (base_radius - apex_radius) * w);
                mesh_.normals.push_back(inside ? -normal : normal);
            }
        }
        has_shading_normals_ = true;

        const std::uint32_t material = current_material();
        for (std::uint32_t i = 0; i < cone_segments; ++i) {
            const std::uint32_t j = (i + 1) % cone_segments;
            const std::uint32_t b0 = first + i, b1 = first + j;
            const std::uint32_t a0 = first + cone_segments + i, a1 = first + cone_segments + j;
            // Seen from outside, b0 b1 a1 and b0 a1 a0 run counter-clockwise; inside-visible cones reverse
            // them.
            if (base_radius > 0.0f) {
                if (inside)
                    add_triangle(b0, a1, b1, material);
                else
                    add_triangle(b0, b1, a1, material);
            }
            if (apex_radius > 0.0f) {
                if (inside)
                    add_triangle(b0, a0, a1, material);
                else
                    add_triangle(b0, a1, a0, material);
            }
        }
    }

    TextReader reader_;
    Scene scene_;
    TriangleMesh mesh_;
    bool has_shading_normals_ = false;
    std::vector<bool> light_colored_;  // per light: the file gave its colour
    bool ambient_given_ = false;
    std::optional<std::uint32_t> current_material_;
    // Scratch space of read_polygon, kept between polygons.
    std::vector<Vec3f> polygon_;
    std::vector<Vec3f> polygon_normals_;
    std::vector<std::uint32_t> triangles_;
};

}  // namespace

Scene load_nff(const std::filesystem::path& file) {
    return NffReader(file).read();
}

}  // namespace lancer
