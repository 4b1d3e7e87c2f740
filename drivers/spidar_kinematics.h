// SPIDAR-G kinematics: string geometry at a pose, and the grip pose from measured string lengths.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "drivers/haptic_device.h"
#include "drivers/spidar_config.h"

namespace rheo::drivers {

using StringMatrix = Eigen::Matrix<double, 6, kSpidarStrings>;  // wrench per unit tension (6 x 8)

/// Geometry of the 8 strings at one grip pose.
struct StringGeometry {
  StringVector length;  // |m_i - (p + R g_i)| [m]
  StringMatrix a;       // column i = [u_i; mu_i]: unit direction grip->motor, (R g_i) x u_i [m]
};

/// Computes lengths and the wrench matrix at `pose` (the structure matrix of the device).
void ComputeStringGeometry(const SpidarConfig& config, const Pose& pose, StringGeometry* out);

/// Pose estimate from string lengths: damped Gauss-Newton, warm-started from the previous
/// tick, a fixed number of iterations per tick. Allocates nothing after construction.
///
/// The rotational unknowns are scaled by the grip radius so that damping acts alike on
/// translation and rotation (unscaled, a 1e-3 damping would dwarf the rotational block, which is
/// of the order of the grip radius squared, and the orientation would lag).
class PoseSolver {
 public:
  /// `config` must be valid (ParseSpidarConfig) and outlive the solver.
  explicit PoseSolver(const SpidarConfig& config);

  /// Restarts from `pose` and clears the length bias (calibration).
  void Reset(const Pose& pose = Pose());

  /// One tick: `iterations` (default: the configured count) damped Gauss-Newton steps towards
  /// the measured lengths [m], then the bias adaptation. Returns false, leaving the previous
  /// estimate in place, when a step produces a non-finite pose.
  bool Update(const StringVector& measured_lengths, int iterations = -1);

  const Pose& pose() const { return pose_; }
  /// Model length minus measured length minus bias after the last update, per string [m].
  const StringVector& residual() const { return residual_; }
  const StringVector& bias() const { return bias_; }
  /// Geometry at the current estimate (valid after Update or Reset).
  const StringGeometry& geometry() const { return geometry_; }

 private:
  const SpidarConfig& config_;
  Pose pose_;
  StringVector bias_ = StringVector::Zero();
  StringVector residual_ = StringVector::Zero();
  StringGeometry geometry_;
};

}  // namespace rheo::drivers
