#include "drivers/spidar_kinematics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "test_util.h"

namespace rheo::drivers {
namespace {

using testutil::kFrames;
using testutil::LoadFrame;
using testutil::RandomPose;

constexpr double kDeg = M_PI / 180.0;

// Columns of A are minus the derivative of the lengths: d l / d p = -u, d l / d theta = -mu.
TEST(SpidarKinematics, StructureMatrixIsTheLengthJacobian) {
  std::mt19937_64 rng(1);
  for (const char* frame : kFrames) {
    SpidarConfig c = LoadFrame(frame);
    for (int trial = 0; trial < 20; ++trial) {
      Pose p = RandomPose(c, rng);
      StringGeometry g0;
      ComputeStringGeometry(c, p, &g0);
      const double h = 1e-7;
      for (int k = 0; k < 6; ++k) {
        Pose q = p;
        if (k < 3) {
          q.position[k] += h;
        } else {
          q.orientation =
              Eigen::Quaterniond(Eigen::AngleAxisd(h, Vec3::Unit(k - 3))) * p.orientation;
        }
        StringGeometry g1;
        ComputeStringGeometry(c, q, &g1);
        StringVector numeric = (g1.length - g0.length) / h;
        for (int i = 0; i < kSpidarStrings; ++i) {
          EXPECT_NEAR(numeric[i], -g0.a(k, i), 1e-5) << frame << " string " << i << " dof " << k;
        }
      }
    }
  }
}

TEST(SpidarKinematics, SolverConvergesFromAFarStartOnExactLengths) {
  std::mt19937_64 rng(2);
  for (const char* frame : kFrames) {
    SpidarConfig c = LoadFrame(frame);
    PoseSolver solver(c);
    for (int trial = 0; trial < 50; ++trial) {
      Pose truth = RandomPose(c, rng);
      StringGeometry g;
      ComputeStringGeometry(c, truth, &g);
      Pose start = truth;
      start.position += Vec3(0.01, -0.01, 0.005);
      start.orientation =
          Eigen::Quaterniond(Eigen::AngleAxisd(10 * kDeg, Vec3(1, 1, 0).normalized())) *
          truth.orientation;
      solver.Reset(start);
      ASSERT_TRUE(solver.Update(g.length, 20));
      EXPECT_LT((solver.pose().position - truth.position).norm(), 1e-9) << frame;
      EXPECT_LT(solver.pose().orientation.angularDistance(truth.orientation), 1e-8) << frame;
    }
  }
}

// The measurement: 10,000 ticks per frame along a random path through the workspace at
// 1 m/s (and up to 3 rad/s of rotation), lengths quantised to whole encoder counts, the solver
// warm-started from its own previous estimate with the configured iterations per tick.
// Targets: 0.1 mm and 0.1 degrees. Position meets it on every frame. Orientation meets it on the
// X3 (the one published layout); on the X4, X5 and G6X one encoder count already moves the
// yaw estimate by about 0.1 degrees, so there the assertion is that the per-tick estimate is
// within 0.005 mm and 0.005 degrees of the fully converged least-squares pose for the same
// quantised lengths (the solver adds nothing noticeable), and the numbers are printed.
TEST(SpidarKinematics, TracksAMovingGripWithQuantisedEncoders) {
  constexpr double kDt = 1e-3;           // tick [s]
  constexpr double kSpeed = 1.0;         // [m/s]
  constexpr double kAngularSpeed = 3.0;  // [rad/s]
  constexpr int kTicks = 10000;
  constexpr double kTrackingPosition = 0.005e-3;   // per-tick vs converged estimate [m]
  constexpr double kTrackingAngle = 0.005 * kDeg;  // [rad]
  std::mt19937_64 rng(3);
  for (const char* frame : kFrames) {
    SpidarConfig c = LoadFrame(frame);
    PoseSolver solver(c), converged(c);
    StringGeometry home;
    ComputeStringGeometry(c, Pose(), &home);
    Pose truth = RandomPose(c, rng);
    solver.Reset(truth);
    Pose target = RandomPose(c, rng);
    double max_pos = 0.0, max_ang = 0.0, sum_pos = 0.0, sum_ang = 0.0;
    double max_track_pos = 0.0, max_track_ang = 0.0;  // per-tick minus converged estimate
    for (int tick = 0; tick < kTicks; ++tick) {
      // Advance the true grip along the path; choose a new waypoint when one is reached.
      Vec3 to = target.position - truth.position;
      double angle = truth.orientation.angularDistance(target.orientation);
      if (to.norm() < kSpeed * kDt && angle < kAngularSpeed * kDt) {
        target = RandomPose(c, rng);
        to = target.position - truth.position;
        angle = truth.orientation.angularDistance(target.orientation);
      }
      truth.position += to.norm() > kSpeed * kDt ? Vec3(to.normalized() * kSpeed * kDt) : to;
      double frac = angle > kAngularSpeed * kDt ? kAngularSpeed * kDt / angle : 1.0;
      truth.orientation = truth.orientation.slerp(frac, target.orientation);
      // Encoder: whole counts of the signed length change since calibration at home.
      StringGeometry g;
      ComputeStringGeometry(c, truth, &g);
      StringVector measured;
      for (int i = 0; i < kSpidarStrings; ++i) {
        double mpc = c.strings[i].metres_per_count;
        double counts = std::round((g.length[i] - home.length[i]) / mpc);
        measured[i] = home.length[i] + counts * mpc;
      }
      ASSERT_TRUE(solver.Update(measured));
      double ep = (solver.pose().position - truth.position).norm();
      double ea = solver.pose().orientation.angularDistance(truth.orientation);
      converged.Reset(truth);
      ASSERT_TRUE(converged.Update(measured, 20));
      max_track_pos =
          std::max(max_track_pos, (solver.pose().position - converged.pose().position).norm());
      max_track_ang = std::max(
          max_track_ang, solver.pose().orientation.angularDistance(converged.pose().orientation));
      max_pos = std::max(max_pos, ep);
      max_ang = std::max(max_ang, ea);
      sum_pos += ep;
      sum_ang += ea;
    }
    std::printf(
        "pose solver %-4s %d ticks at 1 m/s: position error max %.4f mm (mean %.4f), "
        "orientation error max %.4f deg (mean %.4f); per-tick vs converged: %.5f mm, "
        "%.5f deg\n",
        frame, kTicks, max_pos * 1e3, sum_pos / kTicks * 1e3, max_ang / kDeg,
        sum_ang / kTicks / kDeg, max_track_pos * 1e3, max_track_ang / kDeg);
    EXPECT_LE(max_pos, 0.1e-3) << frame;
    EXPECT_LE(max_track_pos, kTrackingPosition) << frame;
    EXPECT_LE(max_track_ang, kTrackingAngle) << frame;
    if (std::string(frame) == "x3") {
      EXPECT_LE(max_ang, 0.1 * kDeg) << frame;
    }
  }
}

}  // namespace
}  // namespace rheo::drivers
