// Transform's constructors and products, and the inverse the instance walk moves rays with.
#include <cmath>
#include <string>

#include "accel/instance/affine.hpp"
#include "lancer/instances.hpp"

namespace lancer {

Transform Transform::translation(Vec3f offset) {
    Transform t;
    t.m[0][3] = offset.x, t.m[1][3] = offset.y, t.m[2][3] = offset.z;
    return t;
}

Transform Transform::rotation(Vec3f axis, float radians) {
    // Rodrigues' formula in double, rounded once per entry.
    const double length =
        std::sqrt(double(axis.x) * axis.x + double(axis.y) * axis.y + double(axis.z) * axis.z);
    const double x = axis.x / length, y = axis.y / length, z = axis.z / length;
    const double c = std::cos(double(radians)), s = std::sin(double(radians)), k = 1.0 - c;
    const double r[3][3] = {{c + x * x * k, x * y * k - z * s, x * z * k + y * s},
                            {y * x * k + z * s, c + y * y * k, y * z * k - x * s},
                            {z * x * k - y * s, z * y * k + x * s, c + z * z * k}};
    Transform t;
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col)
            t.m[row][col] = static_cast<float>(r[row][col]);
    }
    return t;
}

Transform Transform::scaling(Vec3f factors) {
    Transform t;
    t.m[0][0] = factors.x, t.m[1][1] = factors.y, t.m[2][2] = factors.z;
    return t;
}

Vec3f Transform::point(Vec3f p) const {
    Vec3f out;
    for (int r = 0; r < 3; ++r)
        out[r] = static_cast<float>(double(m[r][0]) * p.x + double(m[r][1]) * p.y + double(m[r][2]) * p.z +
                                    double(m[r][3]));
    return out;
}

Vec3f Transform::vector(Vec3f v) const {
    Vec3f out;
    for (int r = 0; r < 3; ++r)
        out[r] = static_cast<float>(double(m[r][0]) * v.x + double(m[r][1]) * v.y + double(m[r][2]) * v.z);
    return out;
}

Vec3f Transform::normal(Vec3f n) const {
    // The cofactor matrix's rows are r1 x r2, r2 x r0, r0 x r1 of the linear part's rows r: (A u) x (A v) =
    // cof(A) (u x v).
    double rows[3][3];
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c)
            rows[r][c] = m[r][c];
    }
    const double x[3] = {n.x, n.y, n.z};
    double out[3];
    for (int r = 0; r < 3; ++r) {
        const double(&a)[3] = rows[(r + 1) % 3];
        const double(&b)[3] = rows[(r + 2) % 3];
        out[r] = (a[1] * b[2] - a[2] * b[1]) * x[0] + (a[2] * b[0] - a[0] * b[2]) * x[1] +
                 (a[0] * b[1] - a[1] * b[0]) * x[2];
    }
    const double norm = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
    if (!(norm > 0.0)) return Vec3f(0.0f);
    return {static_cast<float>(out[0] / norm), static_cast<float>(out[1] / norm),
            static_cast<float>(out[2] / norm)};
}

Transform operator*(const Transform& a, const Transform& b) {
    Transform product;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
            double sum = c == 3 ? double(a.m[r][3]) : 0.0;
            for (int k = 0; k < 3; ++k)
                sum += double(a.m[r][k]) * b.m[k][c];
            product.m[r][c] = static_cast<float>(sum);
        }
    }
    return product;
}

namespace {

double max_row_sum(const double (&matrix)[3][3]) {
    double norm = 0.0;
    for (const auto& row : matrix)
        norm = std::fmax(norm, std::fabs(row[0]) + std::fabs(row[1]) + std::fabs(row[2]));
    return norm;
}

}  // namespace

InverseAffine invert(const Transform& transform, std::string& problem) {
    problem.clear();
    InverseAffine result{};
    for (const auto& row : transform.m) {
        for (const float entry : row) {
            if (!std::isfinite(entry)) {
                problem = "has a NaN or infinite entry";
                return result;
            }
        }
    }
    double a[3][3];
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c)
            a[r][c] = transform.m[r][c];
        result.translation[r] = transform.m[r][3];
    }
    // The adjugate over the determinant; products of two floats are exact in double.
    const double cofactor[3][3] = {
        {a[1][1] * a[2][2] - a[1][2] * a[2][1], a[0][2] * a[2][1] - a[0][1] * a[2][2],
         a[0][1] * a[1][2] - a[0][2] * a[1][1]},
        {a[1][2] * a[2][0] - a[1][0] * a[2][2], a[0][0] * a[2][2] - a[0][2] * a[2][0],
         a[0][2] * a[1][0] - a[0][0] * a[1][2]},
        {a[1][0] * a[2][1] - a[1][1] * a[2][0], a[0][1] * a[2][0] - a[0][0] * a[2][1],
         a[0][0] * a[1][1] - a[0][1] * a[1][0]}};
    const double determinant = a[0][0] * cofactor[0][0] + a[0][1] * cofactor[1][0] + a[0][2] * cofactor[2][0];
    if (determinant == 0.0 || !std::isfinite(determinant)) {
        problem = "is singular (its linear part has determinant 0)";
        return result;
    }
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c)
            result.inverse[r][c] = cofactor[r][c] / determinant;
    }
    result.norm = max_row_sum(a);
    result.condition = result.norm * max_row_sum(result.inverse);
    if (!(result.condition <= kMaxCondition)) {
        problem = "is too ill-conditioned to invert (condition number " + std::to_string(result.condition) +
                  " above 2^29)";
    }
    return result;
}

}  // namespace lancer
