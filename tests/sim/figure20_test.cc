// Paper figure 20 as numbers: one shape, five Voigt elasticities, dropped on the floor. Softer
// Voigt springs must compress more; the table of peak compression, shape error under gravity and
// permanent (plastic) deformation is printed.
#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <cmath>
#include <cstdio>

#include "sim/primitives.h"
#include "sim/sim.h"

namespace rheo::sim {
namespace {

struct DropNumbers {
  double peak_compression = 0.0;  // max of 1 - height / rest height [-]
  double rest_shape_error =
      0.0;               // RMS node offset from the rest shape, at rest under gravity / size
  double plastic = 0.0;  // same, after gravity is removed and the object relaxed / size
};

double ShapeError(const SimObject& s) {
  // Remove the best rigid motion (centroids, then Kabsch rotation); what is left is deformation.
  const auto x = s.positions();
  const auto& r = s.model().rest_positions;
  Vec3 cx = Vec3::Zero(), cr = Vec3::Zero();
  for (size_t i = 0; i < x.size(); ++i) {
    cx += x[i];
    cr += r[i];
  }
  cx /= x.size();
  cr /= x.size();
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < x.size(); ++i) h += (r[i] - cr) * (x[i] - cx).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d rot = svd.matrixV() * d * svd.matrixU().transpose();
  double sum = 0.0;
  for (size_t i = 0; i < x.size(); ++i) sum += ((x[i] - cx) - rot * (r[i] - cr)).squaredNorm();
  return std::sqrt(sum / x.size()) / s.model().size;
}

double Height(const SimObject& s) {
  double lo = 1e30, hi = -1e30;
  for (const Vec3& p : s.positions()) {
    lo = std::min(lo, p.y());
    hi = std::max(hi, p.y());
  }
  return hi - lo;
}

DropNumbers Drop(const TetMesh& mesh, double k_v) {
  Parameters p = FindPreset("soft-jelly")->params;
  p.k_v = k_v;
  auto obj = SimObject::Create(mesh, p, Integrator::kSymplecticEuler);
  EXPECT_TRUE(obj.ok());
  SimObject& s = **obj;
  s.Translate(Vec3(0, 0.15, 0));  // lowest point 15 cm above the floor
  const double h0 = Height(s);
  DropNumbers out;
  for (int k = 0; k < 1000; ++k) {
    s.Step(1e-3);
    out.peak_compression = std::max(out.peak_compression, 1.0 - Height(s) / h0);
  }
  out.rest_shape_error = ShapeError(s);
  EXPECT_TRUE(s.SetParameter("gravity", 0.0).ok());
  for (int k = 0; k < 1000; ++k) s.Step(1e-3);
  out.plastic = ShapeError(s);
  EXPECT_TRUE(s.ComputeDiagnostics().finite);
  return out;
}

TEST(Figure20, PeakCompressionGrowsAsVoigtElasticityFalls) {
  // The sketch-inflated blob stands in as an ellipsoid 10 x 7 x 8 cm (162 tets).
  auto mesh = MakeEllipsoidTetMesh(3, Vec3(0.05, 0.035, 0.04), Vec3(0, 0, 0));
  ASSERT_TRUE(mesh.ok());
  std::printf("  k_v [N/m]  peak compression  rest shape error  plastic deformation\n");
  double previous = -1.0;
  for (double k_v : {800.0, 400.0, 200.0, 100.0, 50.0}) {
    const DropNumbers d = Drop(*mesh, k_v);
    std::printf("  %9.0f  %16.4f  %16.5f  %19.5f\n", k_v, d.peak_compression, d.rest_shape_error,
                d.plastic);
    EXPECT_GT(d.peak_compression, previous) << "k_v = " << k_v;
    EXPECT_LT(d.peak_compression, 0.9) << "k_v = " << k_v;  // squashed, not destroyed
    EXPECT_LE(d.plastic, d.rest_shape_error + 1e-6) << "k_v = " << k_v;
    previous = d.peak_compression;
  }
}

}  // namespace
}  // namespace rheo::sim
