// secondary_view_rays: the diffuse and shadow views of VIEWS.md, made from a canonical view's hits on an
// icosphere.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "lancer/accel.hpp"
#include "lancer/camera.hpp"
#include "lancer/generate.hpp"
#include "lancer/views.hpp"

namespace lancer {
namespace {

class SecondaryViews : public ::testing::Test {
  protected:
    void SetUp() override {
        make_icosphere(3, {0.2f, -0.1f, 0.4f}, 1.0f).append_triangles(triangles_);
        geometry_ = {triangles_, {}};
        const PinholeCamera camera(canonical_view(geometry_.bounds(), 64, 64));
        primary_ = camera.pixel_centre_rays(0, 0, camera.width(), camera.height());
        hits_.resize(primary_.size());
        const std::unique_ptr<Accel> bvh = make_accel("bvh");
        bvh->build(geometry_, {});
        bvh->intersect(primary_, hits_);
        for (const Hit& hit : hits_)
            hit_count_ += hit.hit() ? 1 : 0;
        const Box3f bounds = geometry_.bounds();
        centre_ = (bounds.lo + bounds.hi) * 0.5f;
        radius_ = length(bounds.hi - bounds.lo) * 0.5f;
    }

    // The facing unit normal and the offset origin VIEWS.md asks for at the hit of pixel `pixel`.
    [[nodiscard]] std::pair<Vec3f, Vec3f> normal_and_origin(std::size_t pixel) const {
        const Triangle& tri = triangles_[static_cast<std::size_t>(hits_[pixel].prim)];
        Vec3f normal = normalize(cross(tri.v1 - tri.v0, tri.v2 - tri.v0));
        if (dot(normal, primary_[pixel].direction) > 0.0f) normal = -normal;
        const Vec3f point = primary_[pixel].origin + hits_[pixel].t * primary_[pixel].direction;
        return {normal, point + (1e-4f * radius_) * normal};
    }

    std::vector<Triangle> triangles_;
    Geometry geometry_;
    std::vector<Ray> primary_;
    std::vector<Hit> hits_;
    std::size_t hit_count_ = 0;
    Vec3f centre_;
    float radius_ = 0.0f;
};

TEST_F(SecondaryViews, FourCosineWeightedRaysLeaveEachHitOnItsSide) {
    const std::vector<Ray> rays = secondary_view_rays(SecondaryView::Diffuse, geometry_, primary_, hits_);
    ASSERT_GT(hit_count_, 500u);  // the sphere fills a good part of the view
    ASSERT_EQ(rays.size(), 4 * hit_count_);
    double cosine_sum = 0.0;
    std::size_t next = 0;
    for (std::size_t pixel = 0; pixel < hits_.size(); ++pixel) {
        if (!hits_[pixel].hit()) continue;
        const auto [normal, origin] = normal_and_origin(pixel);
        for (int k = 0; k < 4; ++k) {
            const Ray& ray = rays[next++];
            EXPECT_LT(length(ray.origin - origin), 1e-6f);
            EXPECT_NEAR(length(ray.direction), 1.0f, 1e-5f);
            const float cosine = dot(ray.direction, normal);
            EXPECT_GE(cosine, 0.0f);
            cosine_sum += cosine;
            EXPECT_EQ(ray.tnear, 0.0f);
            EXPECT_EQ(ray.tfar, kInfinity);
        }
        // A pixel's four directions differ.
        EXPECT_NE(rays[next - 1].direction.x, rays[next - 2].direction.x);
    }
    // Cosine-weighted about the normal: E[cos] = 2/3 (standard deviation 0.24 a ray; 5 standard errors of
    // the mean of 4 x 1000 rays is 0.02).
    EXPECT_NEAR(cosine_sum / static_cast<double>(rays.size()), 2.0 / 3.0, 0.02);
}

TEST_F(SecondaryViews, OneShadowRayPerHitEndsJustShortOfTheLight) {
    const std::vector<Ray> rays = secondary_view_rays(SecondaryView::Shadow, geometry_, primary_, hits_);
    ASSERT_EQ(rays.size(), hit_count_);
    const Vec3f light = centre_ + Vec3f(0.5f * radius_, 2.0f * radius_, 1.5f * radius_);
    std::size_t next = 0;
    for (std::size_t pixel = 0; pixel < hits_.size(); ++pixel) {
        if (!hits_[pixel].hit()) continue;
        const Ray& ray = rays[next++];
        EXPECT_LT(length(ray.origin - normal_and_origin(pixel).second), 1e-6f);
        EXPECT_LT(length(ray.origin + ray.direction - light), 1e-5f * radius_);
        EXPECT_EQ(ray.tnear, 0.0f);
        EXPECT_EQ(ray.tfar, 1.0f - 1e-4f);
    }
}

TEST_F(SecondaryViews, MismatchedRaysAndHitsAreRefused) {
    hits_.pop_back();
    EXPECT_THROW(static_cast<void>(secondary_view_rays(SecondaryView::Shadow, geometry_, primary_, hits_)),
                 std::invalid_argument);
}

}  // namespace
}  // namespace lancer
