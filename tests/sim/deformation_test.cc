// The shape change free of rigid motion: a moved and turned copy measures zero, a squashed one
// its squash, whatever rigid motion comes with it.
#include "sim/deformation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>
#include <vector>

namespace rheo::sim {
namespace {

// Random points with their mirror images in every axis: a shape whose best fit to its own
// squash along an axis is the identity (a lopsided shape's best fit may tilt a squash a little).
std::vector<Vec3> Cloud(int n = 50) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> p;
  for (int i = 0; i < n; ++i) {
    const Vec3 q(0.05 * u(rng), 0.03 * u(rng), 0.04 * u(rng));
    for (int m = 0; m < 8; ++m)
      p.emplace_back(m & 1 ? -q.x() : q.x(), m & 2 ? -q.y() : q.y(), m & 4 ? -q.z() : q.z());
  }
  return p;
}

std::vector<Vec3> Moved(const std::vector<Vec3>& p, const Eigen::Matrix3d& r, const Vec3& t) {
  std::vector<Vec3> out;
  for (const Vec3& x : p) out.push_back(r * x + t);
  return out;
}

const Vec3 kUp(0.0, 1.0, 0.0);

TEST(ShapeChange, RigidMotionAloneMeasuresZero) {
  const auto rest = Cloud();
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(0.7, Vec3(0.3, 1.0, -0.2).normalized()).toRotationMatrix();
  const ShapeChange s = MeasureShapeChange(rest, Moved(rest, r, Vec3(0.4, -1.2, 3.0)), kUp);
  EXPECT_NEAR(s.compression, 0.0, 1e-12);
  EXPECT_NEAR(s.rms, 0.0, 1e-12);
  EXPECT_NEAR(s.max, 0.0, 1e-12);
  EXPECT_NEAR(s.rest_extent, s.extent, 1e-12);
  EXPECT_GT(s.rest_extent, 0.05);
}

TEST(ShapeChange, ASquashIsMeasuredThroughATumble) {
  const auto rest = Cloud();
  // 20 % shorter along gravity (volume kept by widening), then turned 90 degrees and dropped.
  const Eigen::Matrix3d squash = Vec3(1.0 / std::sqrt(0.8), 0.8, 1.0 / std::sqrt(0.8)).asDiagonal();
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ()).toRotationMatrix();
  const ShapeChange plain = MeasureShapeChange(rest, Moved(rest, squash, Vec3::Zero()), kUp);
  EXPECT_NEAR(plain.compression, 0.2, 1e-9);
  const ShapeChange turned =
      MeasureShapeChange(rest, Moved(rest, turn * squash, Vec3(0.0, -0.5, 0.1)), kUp);
  EXPECT_NEAR(turned.compression, 0.2, 1e-9);  // the best fit turns it back
  EXPECT_NEAR(turned.rms, plain.rms, 1e-9);
  EXPECT_GT(plain.rms, 1e-3);
}

TEST(ShapeChange, FewerThanTwoNodesAreZero) {
  const std::vector<Vec3> one = {Vec3(1, 2, 3)};
  const ShapeChange s = MeasureShapeChange(one, one, kUp);
  EXPECT_EQ(s.compression, 0.0);
  EXPECT_EQ(s.rms, 0.0);
}

}  // namespace
}  // namespace rheo::sim
