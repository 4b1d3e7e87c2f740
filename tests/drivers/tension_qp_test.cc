#include "drivers/tension_qp.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <limits>
#include <random>

#include "test_util.h"

namespace rheo::drivers {
namespace {

using testutil::kFrames;
using testutil::LoadFrame;
using testutil::RandomPose;

double Objective(const SpidarConfig& c, const StringMatrix& a, const Wrench& w,
                 const StringVector& t) {
  Eigen::Matrix<double, 6, 1> target, err;
  target << w.force, w.torque;
  err = a * t - target;
  return 0.5 * c.tension_qp.force_weight * err.head<3>().squaredNorm() +
         0.5 * c.tension_qp.torque_weight * err.tail<3>().squaredNorm() +
         0.5 * c.tension_qp.regularisation * t.squaredNorm();
}

// Reference: enumerate all 3^8 faces of the box; the convex QP's minimum is the face minimiser
// that lies in the box with the lowest objective. Slow and simple on purpose.
double BruteForceMinimum(const SpidarConfig& c, const StringMatrix& a, const Wrench& w) {
  Eigen::Matrix<double, 6, 1> weight, target;
  weight << Eigen::Vector3d::Constant(c.tension_qp.force_weight),
      Eigen::Vector3d::Constant(c.tension_qp.torque_weight);
  target << w.force, w.torque;
  Eigen::MatrixXd h = a.transpose() * weight.asDiagonal() * a;
  h.diagonal().array() += c.tension_qp.regularisation;
  Eigen::VectorXd g = -(a.transpose() * weight.asDiagonal() * target);
  double best = std::numeric_limits<double>::infinity();
  for (int code = 0; code < 6561; ++code) {
    int state[8];
    for (int i = 0, v = code; i < 8; ++i, v /= 3) state[i] = v % 3;  // 0 free, 1 lower, 2 upper
    StringVector t;
    std::vector<int> f;
    for (int i = 0; i < 8; ++i) {
      t[i] = state[i] == 1 ? c.strings[i].min_tension : c.strings[i].max_tension;
      if (state[i] == 0) f.push_back(i);
    }
    if (!f.empty()) {
      Eigen::MatrixXd hff(f.size(), f.size());
      Eigen::VectorXd rhs(f.size());
      for (size_t r = 0; r < f.size(); ++r) {
        rhs[r] = -g[f[r]];
        for (int j = 0; j < 8; ++j) {
          if (state[j] != 0) rhs[r] -= h(f[r], j) * t[j];
        }
        for (size_t k = 0; k < f.size(); ++k) hff(r, k) = h(f[r], f[k]);
      }
      Eigen::VectorXd x = hff.ldlt().solve(rhs);
      bool inside = true;
      for (size_t r = 0; r < f.size(); ++r) {
        if (x[r] < c.strings[f[r]].min_tension - 1e-12 ||
            x[r] > c.strings[f[r]].max_tension + 1e-12) {
          inside = false;
        }
        t[f[r]] = x[r];
      }
      if (!inside) continue;
    }
    best = std::min(best, Objective(c, a, w, t));
  }
  return best;
}

void ExpectInBounds(const SpidarConfig& c, const StringVector& t) {
  for (int i = 0; i < kSpidarStrings; ++i) {
    EXPECT_GE(t[i], c.strings[i].min_tension) << "string " << i;
    EXPECT_LE(t[i], c.strings[i].max_tension) << "string " << i;
  }
}

// A wrench made by tensions strictly inside the box is feasible: it must be displayed exactly.
TEST(TensionQp, FeasibleWrenchIsDisplayedExactly) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const char* frame : kFrames) {
    SpidarConfig c = LoadFrame(frame);
    TensionSolver solver(c);
    double worst_f = 0.0, worst_t = 0.0;
    for (int trial = 0; trial < 2000; ++trial) {
      Pose p = RandomPose(c, rng);
      StringGeometry g;
      ComputeStringGeometry(c, p, &g);
      StringVector t0;
      for (int i = 0; i < 8; ++i) {
        const auto& s = c.strings[i];
        // Mostly low tensions (the common case), sometimes anywhere in the box.
        double x = trial % 4 == 0 ? u(rng) : 0.3 * u(rng) * u(rng);
        t0[i] = s.min_tension + (0.02 + 0.96 * x) * (s.max_tension - s.min_tension);
      }
      Eigen::Matrix<double, 6, 1> w6 = g.a * t0;
      Wrench w{w6.head<3>(), w6.tail<3>()};
      const TensionSolution& sol = solver.Solve(g.a, w);
      ASSERT_TRUE(sol.converged);
      ExpectInBounds(c, sol.tensions);
      worst_f = std::max(worst_f, (sol.displayed.force - w.force).norm());
      worst_t = std::max(worst_t, (sol.displayed.torque - w.torque).norm());
    }
    std::printf(
        "tension QP %-4s feasible wrenches: max force error %.3g N, torque error %.3g N m\n", frame,
        worst_f, worst_t);
    EXPECT_LE(worst_f, 1e-6) << frame;
    EXPECT_LE(worst_t, 1e-6) << frame;
  }
}

TEST(TensionQp, ZeroWrenchAtHomeNeedsNoNetForce) {
  for (const char* frame : kFrames) {
    SpidarConfig c = LoadFrame(frame);
    TensionSolver solver(c);
    StringGeometry g;
    ComputeStringGeometry(c, Pose(), &g);
    const TensionSolution& sol = solver.Solve(g.a, Wrench());
    ExpectInBounds(c, sol.tensions);
    EXPECT_LE(sol.displayed.force.norm(), 1e-6);
    EXPECT_LE(sol.displayed.torque.norm(), 1e-6);
  }
}

// Random requests, many infeasible (beyond the tension range): always in bounds, and the same
// optimum as exhaustive enumeration of the box faces.
TEST(TensionQp, MatchesExhaustiveReferenceAndStaysInBounds) {
  std::mt19937_64 rng(12);
  std::normal_distribution<double> n(0.0, 1.0);
  for (const char* frame : kFrames) {
    SpidarConfig c = LoadFrame(frame);
    TensionSolver solver(c);
    for (int trial = 0; trial < 40; ++trial) {
      Pose p = RandomPose(c, rng);
      StringGeometry g;
      ComputeStringGeometry(c, p, &g);
      double scale = trial % 2 ? 3.0 : 30.0;  // [N]; 30 N is beyond every frame
      Wrench w{scale * Vec3(n(rng), n(rng), n(rng)), 0.03 * scale * Vec3(n(rng), n(rng), n(rng))};
      const TensionSolution& sol = solver.Solve(g.a, w);
      ASSERT_TRUE(sol.converged);
      ExpectInBounds(c, sol.tensions);
      double reference = BruteForceMinimum(c, g.a, w);
      EXPECT_NEAR(sol.objective, reference, 1e-9 * (1.0 + reference)) << frame << " " << trial;
    }
  }
}

TEST(TensionQp, WarmStartGivesTheColdStartSolution) {
  std::mt19937_64 rng(13);
  SpidarConfig c = LoadFrame("x5");
  TensionSolver warm(c), cold(c);
  Pose p;
  for (int tick = 0; tick < 500; ++tick) {
    p.position = Vec3(0.03 * std::sin(tick * 0.01), 0.02 * std::cos(tick * 0.013), 0.0);
    StringGeometry g;
    ComputeStringGeometry(c, p, &g);
    Wrench w{Vec3(4.0 * std::sin(tick * 0.02), -2.0, 1.0), Vec3(0.0, 0.01, 0.0)};
    const TensionSolution& a = warm.Solve(g.a, w);
    cold.Reset();
    const TensionSolution& b = cold.Solve(g.a, w);
    EXPECT_NEAR(a.objective, b.objective, 1e-9 * (1.0 + b.objective));
    EXPECT_LT((a.displayed.force - b.displayed.force).norm(), 1e-6);
  }
}

}  // namespace
}  // namespace rheo::drivers
