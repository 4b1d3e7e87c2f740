#include "drivers/spidar_kinematics.h"

#include <Eigen/Cholesky>
#include <cmath>

namespace rheo::drivers {

void ComputeStringGeometry(const SpidarConfig& config, const Pose& pose, StringGeometry* out) {
  const Eigen::Matrix3d r = pose.orientation.toRotationMatrix();
  for (int i = 0; i < kSpidarStrings; ++i) {
    const SpidarString& s = config.strings[i];
    const Vec3 rg = r * s.grip_point;
    const Vec3 w = s.motor_exit - (pose.position + rg);
    const double len = w.norm();
    out->length[i] = len;
    // A zero-length string has no direction; the guards reject such lengths before they matter.
    const Vec3 u = len > 0.0 ? Vec3(w / len) : Vec3::Zero();
    out->a.col(i).head<3>() = u;
    out->a.col(i).tail<3>() = rg.cross(u);
  }
}

PoseSolver::PoseSolver(const SpidarConfig& config) : config_(config) {
  Reset();
}

void PoseSolver::Reset(const Pose& pose) {
  pose_ = pose;
  pose_.orientation.normalize();
  bias_.setZero();
  residual_.setZero();
  ComputeStringGeometry(config_, pose_, &geometry_);
}

bool PoseSolver::Update(const StringVector& measured, int iterations) {
  const PoseSolverConfig& opt = config_.pose_solver;
  if (iterations < 0) iterations = opt.iterations;
  const double scale = config_.grip_radius;  // rotation unknown is scale * angle [m]
  Pose next = pose_;
  StringGeometry g = geometry_;
  for (int it = 0; it < iterations; ++it) {
    ComputeStringGeometry(config_, next, &g);
    const StringVector e = g.length - measured - bias_;
    StringMatrix a = g.a;
    a.bottomRows<3>() /= scale;
    Eigen::Matrix<double, 6, 6> n = a * a.transpose();
    n.diagonal().array() += opt.damping;
    const Eigen::Matrix<double, 6, 1> delta = n.ldlt().solve(a * e);
    next.position += delta.head<3>();
    Vec3 d = delta.tail<3>() / scale;
    const double angle = d.norm();
    if (angle > opt.max_rotation_step) d *= opt.max_rotation_step / angle;
    if (angle > 0.0) {
      next.orientation =
          Eigen::Quaterniond(Eigen::AngleAxisd(d.norm(), d.normalized())) * next.orientation;
      next.orientation.normalize();
    }
  }
  ComputeStringGeometry(config_, next, &g);
  if (!next.position.allFinite() || !next.orientation.coeffs().allFinite() ||
      !g.length.allFinite()) {
    return false;
  }
  pose_ = next;
  geometry_ = g;
  residual_ = g.length - measured - bias_;
  // The bias slowly absorbs what no pose explains (string stretch, calibration offsets).
  bias_ += opt.bias_gain * residual_;
  return true;
}

}  // namespace rheo::drivers
