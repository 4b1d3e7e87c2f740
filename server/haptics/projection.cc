#include "haptics/projection.h"

#include <Eigen/Dense>
#include <cmath>
#include <limits>

namespace rheo::haptics::internal {
namespace {

bool Feasible(const Vec3& y, std::span<const HalfSpace> h, double tol) {
  for (const HalfSpace& s : h) {
    if (s.n.dot(y) < s.c - tol) return false;
  }
  return true;
}

void Consider(const Vec3& t, const Vec3& y, std::span<const HalfSpace> h, double tol, Vec3& best,
              double& best_d2) {
  const double d2 = (y - t).squaredNorm();
  if (d2 < best_d2 && Feasible(y, h, tol)) {
    best = y;
    best_d2 = d2;
  }
}

}  // namespace

bool ProjectOntoHalfSpaces(const Vec3& t, std::span<const HalfSpace> h, double tol, Vec3& out) {
  if (Feasible(t, h, tol)) {
    out = t;
    return true;
  }
  const int m = static_cast<int>(h.size());
  double best_d2 = std::numeric_limits<double>::infinity();
  Vec3 best = t;
  constexpr double kMinDet = 1e-12;
  for (int i = 0; i < m; ++i) {
    const double li = h[i].c - h[i].n.dot(t);
    if (li > 0.0) Consider(t, t + li * h[i].n, h, tol, best, best_d2);
  }
  for (int i = 0; i < m; ++i) {
    for (int j = i + 1; j < m; ++j) {
      const double g = h[i].n.dot(h[j].n);
      const double det = 1.0 - g * g;
      if (det < kMinDet) continue;
      const double ri = h[i].c - h[i].n.dot(t), rj = h[j].c - h[j].n.dot(t);
      const double li = (ri - g * rj) / det, lj = (rj - g * ri) / det;
      if (li < 0.0 || lj < 0.0) continue;
      Consider(t, t + li * h[i].n + lj * h[j].n, h, tol, best, best_d2);
    }
  }
  for (int i = 0; i < m; ++i) {
    for (int j = i + 1; j < m; ++j) {
      for (int k = j + 1; k < m; ++k) {
        Eigen::Matrix3d n;
        n.col(0) = h[i].n;
        n.col(1) = h[j].n;
        n.col(2) = h[k].n;
        const double det = n.determinant();
        if (std::abs(det) < kMinDet) continue;
        const Eigen::Matrix3d gram = n.transpose() * n;
        const Vec3 rhs(h[i].c - h[i].n.dot(t), h[j].c - h[j].n.dot(t), h[k].c - h[k].n.dot(t));
        const Vec3 lambda = gram.inverse() * rhs;
        if ((lambda.array() < 0.0).any()) continue;
        Consider(t, t + n * lambda, h, tol, best, best_d2);
      }
    }
  }
  if (!std::isfinite(best_d2)) return false;
  out = best;
  return true;
}

}  // namespace rheo::haptics::internal
