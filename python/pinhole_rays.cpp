#include "pinhole_rays.hpp"

#include <array>
#include <cmath>
#include <numbers>
#include <span>
#include <vector>

#include "array_arguments.hpp"
#include "lancer/vec3d.hpp"

namespace lancer::python {
namespace {

void check_image_size(int width_px, int height_px) {
    if (width_px <= 0 || height_px <= 0 || width_px > 1 << 16 || height_px > 1 << 16)
        throw py::value_error("width_px, height_px: expected sizes in [1, 65536]");
}

// Open3D's pinhole rays, (height_px, width_px, 6), from a 3x3 intrinsic matrix K and a 4x4 world-to-camera
// transform [R t], both row by row: pixel (x, y)'s ray starts at the camera's centre, -R^T t, along
// R^T K^-1 (x + 0.5, y + 0.5, 1), in double as Open3D computes it, rounded to float32 once. Throws ValueError
// for a K that is not invertible.
py::array pinhole_rays(std::span<const double, 9> intrinsic, std::span<const double, 16> extrinsic,
                       int width_px, int height_px) {
    // K^-1 by cofactors.
    const auto at = [&](int row, int column) {
        return intrinsic[static_cast<std::size_t>(3 * row + column)];
    };
    const double cofactor[3][3] = {
        {at(1, 1) * at(2, 2) - at(1, 2) * at(2, 1), at(0, 2) * at(2, 1) - at(0, 1) * at(2, 2),
         at(0, 1) * at(1, 2) - at(0, 2) * at(1, 1)},
        {at(1, 2) * at(2, 0) - at(1, 0) * at(2, 2), at(0, 0) * at(2, 2) - at(0, 2) * at(2, 0),
         at(0, 2) * at(1, 0) - at(0, 0) * at(1, 2)},
        {at(1, 0) * at(2, 1) - at(1, 1) * at(2, 0), at(0, 1) * at(2, 0) - at(0, 0) * at(2, 1),
         at(0, 0) * at(1, 1) - at(0, 1) * at(1, 0)}};
    const double determinant =
        at(0, 0) * cofactor[0][0] + at(0, 1) * cofactor[1][0] + at(0, 2) * cofactor[2][0];
    if (!(std::abs(determinant) > 0.0) || !std::isfinite(1.0 / determinant))
        throw py::value_error("intrinsic_matrix: expected an invertible matrix");
    const auto transform = [&](int row, int column) {
        return extrinsic[static_cast<std::size_t>(4 * row + column)];
    };
    // A singular R (an all-zero matrix, a dropped row) maps every pixel into a plane or onto zero: rays of
    // zero or parallel directions, which trace as misses without a word.
    const double rotation_determinant =
        transform(0, 0) * (transform(1, 1) * transform(2, 2) - transform(1, 2) * transform(2, 1)) -
        transform(0, 1) * (transform(1, 0) * transform(2, 2) - transform(1, 2) * transform(2, 0)) +
        transform(0, 2) * (transform(1, 0) * transform(2, 1) - transform(1, 1) * transform(2, 0));
    if (!(std::abs(rotation_determinant) > 0.0) || !std::isfinite(1.0 / rotation_determinant))
        throw py::value_error("extrinsic_matrix: expected an invertible rotation R in its upper left 3 x 3");
    double to_world[3][3];  // R^T K^-1
    for (int row = 0; row < 3; ++row) {
        for (int column = 0; column < 3; ++column) {
            double sum = 0.0;
            for (int j = 0; j < 3; ++j)
                sum += transform(j, row) * cofactor[j][column] / determinant;
            to_world[row][column] = sum;
        }
    }
    double centre[3];  // -R^T t
    for (int row = 0; row < 3; ++row)
        centre[row] = -(transform(0, row) * transform(0, 3) + transform(1, row) * transform(1, 3) +
                        transform(2, row) * transform(2, 3));
    py::array_t<float> rays(std::vector<py::ssize_t>{height_px, width_px, 6});
    float* out = rays.mutable_data();
    for (int y = 0; y < height_px; ++y) {
        for (int x = 0; x < width_px; ++x, out += 6) {
            const double pixel[3] = {x + 0.5, y + 0.5, 1.0};
            for (int row = 0; row < 3; ++row) {
                out[row] = static_cast<float>(centre[row]);
                out[3 + row] = static_cast<float>(to_world[row][0] * pixel[0] + to_world[row][1] * pixel[1] +
                                                  to_world[row][2] * pixel[2]);
            }
        }
    }
    return open3d_like(rays);
}

}  // namespace

py::array create_rays_pinhole(double fov_deg, const py::object& center, const py::object& eye,
                              const py::object& up, int width_px, int height_px) {
    if (!(fov_deg > 0.0 && fov_deg < 180.0)) throw py::value_error("fov_deg: expected a value in (0, 180)");
    check_image_size(width_px, height_px);
    // Open3D's look-at camera, traced through the matrix form as Open3D traces it: the rows of R are x = up x
    // forward, y = forward x x and forward, so pixel (0, 0) lies towards -x and +y of the usual camera;
    // focal length 0.5 width / tan(fov / 2) in pixels, the principal point at the image's centre. The frame
    // is made in double, as Open3D makes it (docs/python.md, "The API").
    const Vec3d target(vec3_argument(center, "center")), origin(vec3_argument(eye, "eye"));
    const Vec3d forward = normalize(target - origin);
    const Vec3d x_axis = normalize(cross(Vec3d(vec3_argument(up, "up")), forward));
    if (!std::isfinite(forward.x) || !std::isfinite(x_axis.x))
        throw py::value_error(
            "center, eye, up: the eye must differ from the centre and up must not be along the view");
    const Vec3d y_axis = normalize(cross(forward, x_axis));
    const double focal = 0.5 * width_px / std::tan(0.5 * fov_deg * std::numbers::pi / 180.0);
    std::array<double, 9> intrinsic{};  // K, row by row
    intrinsic[0] = intrinsic[4] = focal;
    intrinsic[2] = 0.5 * width_px, intrinsic[5] = 0.5 * height_px, intrinsic[8] = 1.0;
    std::array<double, 16> extrinsic{};  // [R -R eye], last row (0 0 0 1)
    extrinsic[15] = 1.0;
    for (std::size_t row = 0; row < 3; ++row) {
        const Vec3d& axis = row == 0 ? x_axis : row == 1 ? y_axis : forward;
        extrinsic[4 * row] = axis.x, extrinsic[4 * row + 1] = axis.y, extrinsic[4 * row + 2] = axis.z;
        extrinsic[4 * row + 3] = -dot(axis, origin);
    }
    return pinhole_rays(intrinsic, extrinsic, width_px, height_px);
}

py::array create_rays_pinhole(const py::object& intrinsic_matrix, const py::object& extrinsic_matrix,
                              int width_px, int height_px) {
    const std::vector<double> intrinsic = matrix_argument(intrinsic_matrix, "intrinsic_matrix", 3, 3);
    const std::vector<double> extrinsic = matrix_argument(extrinsic_matrix, "extrinsic_matrix", 4, 4);
    check_image_size(width_px, height_px);
    return pinhole_rays(std::span<const double, 9>(intrinsic.data(), 9),
                        std::span<const double, 16>(extrinsic.data(), 16), width_px, height_px);
}

}  // namespace lancer::python
