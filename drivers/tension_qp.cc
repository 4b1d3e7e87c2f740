#include "drivers/tension_qp.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

namespace rheo::drivers {
namespace {

// Fixed-capacity dynamic sizes: the free-set subproblem lives on the stack.
using SubMatrix =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kSpidarStrings, kSpidarStrings>;
using SubVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kSpidarStrings, 1>;

StringVector BoundsFrom(const SpidarConfig& c, bool upper) {
  StringVector v;
  for (int i = 0; i < kSpidarStrings; ++i) {
    v[i] = upper ? c.strings[i].max_tension : c.strings[i].min_tension;
  }
  return v;
}

}  // namespace

TensionSolver::TensionSolver(const TensionQpConfig& options, const StringVector& min_tension,
                             const StringVector& max_tension)
    : opt_(options), lo_(min_tension), hi_(max_tension) {
  Reset();
}

TensionSolver::TensionSolver(const SpidarConfig& config)
    : TensionSolver(config.tension_qp, BoundsFrom(config, false), BoundsFrom(config, true)) {}

void TensionSolver::Reset() {
  active_.fill(Bound::kLower);
  solution_ = TensionSolution();
  solution_.tensions = lo_;
}

const TensionSolution& TensionSolver::Solve(const StringMatrix& a, const Wrench& requested) {
  Eigen::Matrix<double, 6, 1> weight, w;
  weight << Eigen::Vector3d::Constant(opt_.force_weight),
      Eigen::Vector3d::Constant(opt_.torque_weight);
  w << requested.force, requested.torque;
  const StringMatrix wa = weight.asDiagonal() * a;
  Eigen::Matrix<double, kSpidarStrings, kSpidarStrings> h = a.transpose() * wa;
  h.diagonal().array() += opt_.regularisation;
  const StringVector g = -wa.transpose() * w;

  // Warm start: previous active set, free tensions from the previous solution.
  StringVector t = solution_.tensions;
  for (int i = 0; i < kSpidarStrings; ++i) {
    if (active_[i] == Bound::kLower) t[i] = lo_[i];
    if (active_[i] == Bound::kUpper) t[i] = hi_[i];
    t[i] = std::clamp(t[i], lo_[i], hi_[i]);
  }
  const double tol =
      1e-13 * (1.0 + g.cwiseAbs().maxCoeff() + h.diagonal().maxCoeff() * hi_.maxCoeff());

  int iterations = 0;
  bool converged = false;
  std::array<int, kSpidarStrings> free_index{};
  SubMatrix hff;
  SubVector rhs, x;
  Eigen::LLT<SubMatrix> llt(kSpidarStrings);
  while (iterations <= opt_.max_iterations) {
    int nf = 0;
    for (int i = 0; i < kSpidarStrings; ++i) {
      if (active_[i] == Bound::kFree) free_index[nf++] = i;
    }
    if (nf > 0) {
      hff.resize(nf, nf);
      rhs.resize(nf);
      for (int r = 0; r < nf; ++r) {
        const int i = free_index[r];
        double b = -g[i];
        for (int j = 0; j < kSpidarStrings; ++j) {
          if (active_[j] != Bound::kFree) b -= h(i, j) * t[j];
        }
        rhs[r] = b;
        for (int c = 0; c < nf; ++c) hff(r, c) = h(i, free_index[c]);
      }
      llt.compute(hff);
      x = llt.solve(rhs);
      // Longest step towards x that stays in the box; the first string to hit a bound stops it.
      double alpha = 1.0;
      int blocking = -1;
      Bound blocking_bound = Bound::kFree;
      for (int r = 0; r < nf; ++r) {
        const int i = free_index[r];
        const double d = x[r] - t[i];
        if (x[r] < lo_[i] && d < 0.0) {
          const double s = (lo_[i] - t[i]) / d;
          if (s < alpha) alpha = s, blocking = i, blocking_bound = Bound::kLower;
        } else if (x[r] > hi_[i] && d > 0.0) {
          const double s = (hi_[i] - t[i]) / d;
          if (s < alpha) alpha = s, blocking = i, blocking_bound = Bound::kUpper;
        }
      }
      alpha = std::max(alpha, 0.0);
      for (int r = 0; r < nf; ++r) {
        const int i = free_index[r];
        t[i] = std::clamp(t[i] + alpha * (x[r] - t[i]), lo_[i], hi_[i]);
      }
      if (blocking >= 0) {
        active_[blocking] = blocking_bound;
        t[blocking] = blocking_bound == Bound::kLower ? lo_[blocking] : hi_[blocking];
        ++iterations;
        continue;
      }
    }
    // Subproblem optimal: release the bound string whose multiplier has the wrong sign most.
    const StringVector grad = h * t + g;
    int release = -1;
    double worst = tol;
    for (int i = 0; i < kSpidarStrings; ++i) {
      const double violation = active_[i] == Bound::kLower   ? -grad[i]
                               : active_[i] == Bound::kUpper ? grad[i]
                                                             : 0.0;
      if (violation > worst) worst = violation, release = i;
    }
    if (release < 0) {
      converged = true;
      break;
    }
    active_[release] = Bound::kFree;
    ++iterations;
  }

  solution_.tensions = t;
  const Eigen::Matrix<double, 6, 1> shown = a * t;
  solution_.displayed.force = shown.head<3>();
  solution_.displayed.torque = shown.tail<3>();
  const Eigen::Matrix<double, 6, 1> err = shown - w;
  solution_.objective =
      0.5 * err.dot(weight.asDiagonal() * err) + 0.5 * opt_.regularisation * t.squaredNorm();
  solution_.iterations = iterations;
  solution_.converged = converged;
  return solution_;
}

}  // namespace rheo::drivers
