#include "sim/deformation.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace rheo::sim {

ShapeChange MeasureShapeChange(std::span<const Vec3> rest, std::span<const Vec3> current,
                               const Vec3& up) {
  ShapeChange out;
  const size_t n = std::min(rest.size(), current.size());
  if (n < 2) return out;
  Vec3 c0 = Vec3::Zero(), c1 = Vec3::Zero();
  for (size_t i = 0; i < n; ++i) {
    c0 += rest[i];
    c1 += current[i];
  }
  c0 /= static_cast<double>(n);
  c1 /= static_cast<double>(n);
  // The rotation R minimising sum |R (x_i - c1) - (r_i - c0)|^2 (Kabsch): from the SVD of the
  // cross-covariance, with the sign fixed so that R is a rotation, not a reflection.
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) h += (current[i] - c1) * (rest[i] - c0).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0) d(2, 2) = -1.0;
  const Eigen::Matrix3d r = svd.matrixV() * d * svd.matrixU().transpose();
  double lo0 = 0, hi0 = 0, lo1 = 0, hi1 = 0, sum2 = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const Vec3 fitted = r * (current[i] - c1) + c0;
    const double y0 = rest[i].dot(up), y1 = fitted.dot(up);
    if (i == 0 || y0 < lo0) lo0 = y0;
    if (i == 0 || y0 > hi0) hi0 = y0;
    if (i == 0 || y1 < lo1) lo1 = y1;
    if (i == 0 || y1 > hi1) hi1 = y1;
    const double e2 = (fitted - rest[i]).squaredNorm();
    sum2 += e2;
    out.max = std::max(out.max, std::sqrt(e2));
  }
  out.rest_extent = hi0 - lo0;
  out.extent = hi1 - lo1;
  out.compression = out.rest_extent > 0.0 ? 1.0 - out.extent / out.rest_extent : 0.0;
  out.rms = std::sqrt(sum2 / static_cast<double>(n));
  return out;
}

}  // namespace rheo::sim
