// The ray tree of Ferreira & Mendoza 2011, section 5.4, walked without recursion. Whitted's model (Ferreira &
// Mendoza 2011, 4.3),
//   I = Ia + kd sum_j (N.L_j) + ks S + kt T,
// is linear in S and T, so a node's value is its local term plus its children's values scaled by ks and kt:
// the value of the whole tree is the sum over its nodes of (product of the ks and kt on the path from the
// eye) x (local term). A node therefore carries that product, its weight, and adds its local term straight to
// its camera sample; nothing flows back up, and the tree needs neither parent pointers nor the seed's
// "visited" flags. Its nodes are kept in an explicit work list, one level at a time: the list of level k is
// traced as one batch, and its reflected and refracted children make the list of level k + 1, down to the
// maximum depth (the eye ray is depth 1, as in the SPD). The shadow rays of a level are one batch of
// occlusion queries.
#include "render/whitted.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "render/grouped_batch.hpp"
#include "render/optics.hpp"

namespace lancer {
namespace {

// One node of the ray tree (Ferreira & Mendoza 2011, Tableau 2, without the pointers the weights make
// unnecessary).
struct RayNode {
    Ray ray;               // unit direction, origin already moved off the surface it leaves
    float weight;          // product of the ks and kt met since the eye ray
    std::uint32_t sample;  // the camera sample (tile-local) its light goes to
    int depth;             // 1 for the eye ray
};

// What a shadow ray's light adds to its sample when nothing blocks the ray.
struct LightContribution {
    Vec3f radiance;
    std::uint32_t sample;
};

// What shading one level of the tree leaves to do, besides the light already added to the samples, and the
// rays counted so far over all levels.
struct LevelOutput {
    std::vector<RayNode> children;
    std::vector<Ray> shadow_rays;
    std::vector<LightContribution> shadow_light;    // one per shadow ray
    std::vector<std::uint32_t> shadow_light_index;  // the scene light each shadow ray goes to
    RayCounts counts;                               // not cleared between levels

    void clear() { children.clear(), shadow_rays.clear(), shadow_light.clear(), shadow_light_index.clear(); }
};

// The surface as the arriving ray sees it: which side it came from is decided by the geometric normal (the
// sign of I.N, Ferreira & Mendoza 2011, 4.2), and both normals are turned towards that side.
struct FacingSurface {
    Vec3f position;
    Vec3f geometric;  // unit, facing the incoming ray
    Vec3f shading;    // unit, flipped along with the geometric normal
    bool from_back;   // the ray arrived against the primitive's own normal: it leaves the medium
};

FacingSurface facing(const SurfacePoint& surface, Vec3f direction) {
    const bool from_back = dot(surface.geometric_normal, direction) > 0.0f;
    return {surface.position, from_back ? -surface.geometric_normal : surface.geometric_normal,
            from_back ? -surface.shading_normal : surface.shading_normal, from_back};
}

// An interpolated normal can send a mirror or refracted ray to the wrong side of the facet it leaves (a
// silhouette seen at a grazing angle); the facet's own normal then decides the direction.
Vec3f mirror_direction(Vec3f direction, const FacingSurface& surface) {
    const Vec3f mirror = reflect(direction, surface.shading);
    return dot(mirror, surface.geometric) > 0.0f ? mirror : reflect(direction, surface.geometric);
}

struct Transmission {
    Vec3f direction;
    float cos_incident;  // with the normal that bent it, for Fresnel
};

std::optional<Transmission> transmitted_direction(Vec3f direction, const FacingSurface& surface, float eta) {
    if (const std::optional<Vec3f> bent = refract(direction, surface.shading, eta);
        bent && dot(*bent, surface.geometric) < 0.0f) {
        return Transmission{*bent, -dot(direction, surface.shading)};
    }
    if (const std::optional<Vec3f> bent = refract(direction, surface.geometric, eta)) {
        return Transmission{*bent, -dot(direction, surface.geometric)};
    }
    return std::nullopt;  // total internal reflection
}

class LevelShader {
  public:
    LevelShader(const Scene& scene, const SceneIntersector& intersector, const RenderOptions& options,
                std::vector<Vec3f>& radiance, LevelOutput& out)
        : scene_(scene), intersector_(intersector), options_(options), radiance_(radiance), out_(out) {}

    void shade(const RayNode& node, const InstanceHit& hit) const {
        if (!hit.hit()) {
            radiance_[node.sample] += node.weight * scene_.background;
            return;
        }
        const SurfacePoint point = intersector_.surface(node.ray, hit);
        const Material& material = scene_.materials[point.material];
        const FacingSurface surface = facing(point, node.ray.direction);
        // The ambient light is reflected like the diffuse term: a mirror or a clear glass shows none of it.
        radiance_[node.sample] += node.weight * material.kd * (scene_.ambient * point.color);
        add_lights(node, material, point.color, surface);
        if (node.depth < options_.max_depth) add_children(node, material, surface);
    }

  private:
    // Ferreira & Mendoza 2011, 4.3: kd sum_j (N.L_j), with the surface colour, plus a Phong highlight ks
    // (V.L)^shininess around the mirror direction V, both scaled by the light's colour and only where its
    // shadow ray is free. As the SPD asks, no shadow ray is cast when the normal faces away from the light:
    // the shading normal (no light) or the facet's normal (the ray would leave through the surface).
    void add_lights(const RayNode& node, const Material& material, Vec3f color,
                    const FacingSurface& surface) const {
        const bool highlight = material.ks > 0.0f && material.shininess > 0.0f;
        if (material.kd <= 0.0f && !highlight) return;
        const Vec3f view_mirror = reflect(node.ray.direction, surface.shading);
        const Vec3f origin = offset_ray_origin(surface.position, surface.geometric);
        for (std::size_t light_index = 0; light_index < scene_.lights.size(); ++light_index) {
            const Light& light = scene_.lights[light_index];
            const Vec3f to_light = normalize(light.position - surface.position);
            const float cos_light = dot(surface.shading, to_light);
            if (!(cos_light > 0.0f) || !(dot(surface.geometric, to_light) > 0.0f)) continue;
            Vec3f reflected = material.kd * cos_light * color;
            if (highlight) {
                const float cos_mirror = dot(view_mirror, to_light);
                if (cos_mirror > 0.0f)
                    reflected += Vec3f(material.ks * std::pow(cos_mirror, material.shininess));
            }
            // t in [0, 1] reaches the light exactly: the direction is not normalised.
            out_.shadow_rays.push_back({origin, light.position - origin, 0.0f, 1.0f});
            out_.shadow_light.push_back({node.weight * (reflected * light.color), node.sample});
            out_.shadow_light_index.push_back(static_cast<std::uint32_t>(light_index));
        }
    }

    // Ferreira & Mendoza 2011, 4.1 and 4.2: the mirror ray takes ks; the refracted ray takes kt, or hands it
    // to the mirror ray under total internal reflection (the SPD still spawns that ray). With Fresnel on, kt
    // is split between the two by the dielectric reflectance. Children whose weight is not above the minimum
    // are cut off.
    void add_children(const RayNode& node, const Material& material, const FacingSurface& surface) const {
        float reflection_weight = material.ks;
        float refraction_weight = 0.0f;
        std::optional<Transmission> transmission;
        if (material.kt > 0.0f) {
            // NFF writes index 0 on many materials; a transparent one without a usable index lets light
            // through unbent.
            const float ior = material.ior > 0.0f ? material.ior : 1.0f;
            const float eta = surface.from_back ? ior : 1.0f / ior;  // n_i / n_t: leaving or entering
            transmission = transmitted_direction(node.ray.direction, surface, eta);
            if (!transmission) {
                reflection_weight += material.kt;
            } else {
                const float reflectance =
                    options_.fresnel ? fresnel_dielectric(transmission->cos_incident, eta) : 0.0f;
                reflection_weight += material.kt * reflectance;
                refraction_weight = material.kt * (1.0f - reflectance);
            }
        }
        const float mirror_weight = node.weight * reflection_weight;
        if (mirror_weight > options_.min_weight) {
            const Ray ray{offset_ray_origin(surface.position, surface.geometric),
                          mirror_direction(node.ray.direction, surface), 0.0f, kInfinity};
            out_.children.push_back({ray, mirror_weight, node.sample, node.depth + 1});
            ++out_.counts.reflection;
        }
        const float transmitted_weight = node.weight * refraction_weight;
        if (transmission && transmitted_weight > options_.min_weight) {
            const Ray ray{offset_ray_origin(surface.position, -surface.geometric), transmission->direction,
                          0.0f, kInfinity};
            out_.children.push_back({ray, transmitted_weight, node.sample, node.depth + 1});
            ++out_.counts.refraction;
        }
    }

    const Scene& scene_;
    const SceneIntersector& intersector_;
    const RenderOptions& options_;
    std::vector<Vec3f>& radiance_;
    LevelOutput& out_;
};

}  // namespace

WhittedTracer::WhittedTracer(const Scene& scene, const SceneIntersector& intersector,
                             const PinholeCamera& camera, const RenderOptions& options)
    : scene_(scene), intersector_(intersector), camera_(camera), options_(options) {}

RayCounts WhittedTracer::render_tile(int x0, int y0, int x1, int y1, Image& image) const {
    const auto samples_per_pixel = static_cast<std::uint32_t>(options_.samples_per_pixel);
    const auto pixel_count = static_cast<std::size_t>(x1 - x0) * static_cast<std::size_t>(y1 - y0);
    std::vector<Vec3f> radiance(pixel_count * samples_per_pixel);

    std::vector<RayNode> level;
    level.reserve(radiance.size());
    std::uint32_t sample = 0;
    for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
            for (std::uint32_t s = 0; s < samples_per_pixel; ++s, ++sample) {
                const PixelSample offset = pixel_sample(s, samples_per_pixel);
                const Ray ray =
                    camera_.generate(static_cast<float>(x) + offset.x, static_cast<float>(y) + offset.y);
                level.push_back({ray, 1.0f, sample, 1});
            }
        }
    }

    LevelOutput out;
    out.counts.primary = level.size();
    std::vector<Ray> rays;
    std::vector<InstanceHit> hits;
    std::vector<std::uint8_t> blocked;
    GroupedBatch<std::uint8_t> shadows;
    const LevelShader shader(scene_, intersector_, options_, radiance, out);
    // The first level holds the camera rays, in pixel order: the structure's coherent path.
    bool primary = true;
    while (!level.empty()) {
        rays.clear();
        for (const RayNode& node : level)
            rays.push_back(node.ray);
        hits.assign(rays.size(), InstanceHit{});
        if (primary) {
            intersector_.intersect_coherent(rays, hits);
        } else {
            intersector_.intersect(rays, hits);
        }
        primary = false;

        out.clear();
        for (std::size_t i = 0; i < level.size(); ++i)
            shader.shade(level[i], hits[i]);

        shadows.trace(out.shadow_rays, out.shadow_light_index, scene_.lights.size(), blocked,
                      [&](std::span<const Ray> batch, std::span<std::uint8_t> batch_blocked) {
                          intersector_.occluded(batch, batch_blocked);
                      });
        for (std::size_t i = 0; i < blocked.size(); ++i) {
            if (blocked[i] == 0) radiance[out.shadow_light[i].sample] += out.shadow_light[i].radiance;
        }
        out.counts.shadow += out.shadow_rays.size();
        std::swap(level, out.children);
    }

    const float inverse_count = 1.0f / static_cast<float>(samples_per_pixel);
    std::size_t first = 0;
    for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x, first += samples_per_pixel) {
            Vec3f sum{};
            for (std::uint32_t s = 0; s < samples_per_pixel; ++s)
                sum += radiance[first + s];
            image.at(x, y) = sum * inverse_count;
        }
    }
    return out.counts;
}

}  // namespace lancer
