// SPIDAR-G wrench-to-tension distribution: a box-constrained QP, active set, warm-started.
#pragma once

#include <array>

#include "drivers/haptic_device.h"
#include "drivers/spidar_config.h"
#include "drivers/spidar_kinematics.h"

namespace rheo::drivers {

/// Result of one tension solve.
struct TensionSolution {
  StringVector tensions = StringVector::Zero();  // within [min, max] per string [N]
  Wrench displayed;                              // A t: what the tensions produce
  double objective = 0.0;  // 0.5 |W (A t - w)|^2 + 0.5 s |t|^2 at the solution
  int iterations = 0;      // active-set changes this solve
  bool converged = false;  // false only when max_iterations was reached (t is still in bounds)
};

/// Chooses string tensions t in [t_min, t_max] minimising
///   0.5 lt |f(t) - f|^2 + 0.5 lr |tau(t) - tau|^2 + 0.5 s |t|^2,  f(t), tau(t) = A t,
/// by a primal active-set method warm-started from the previous solve's active set.
///
/// The published tie-break weight (s = 0.3) trades wrench accuracy for lower tensions; here s is
/// a tiny regularisation (default 1e-10) so that a feasible wrench is displayed exactly (within
/// about 1e-7 N) and, among the exact solutions, the lowest tensions are chosen. Every iterate
/// stays inside the box, so even an interrupted solve gives valid tensions. Allocates nothing.
class TensionSolver {
 public:
  /// `min_tension`, `max_tension`: bounds per string [N], min > 0 and max > min.
  TensionSolver(const TensionQpConfig& options, const StringVector& min_tension,
                const StringVector& max_tension);
  /// Bounds and weights from a validated config (max tension as the config says).
  explicit TensionSolver(const SpidarConfig& config);

  /// Solves for `requested` with structure matrix `a` (ComputeStringGeometry).
  const TensionSolution& Solve(const StringMatrix& a, const Wrench& requested);

  /// Forgets the warm start: the next solve starts with every string at its lower bound.
  void Reset();

  const TensionSolution& solution() const { return solution_; }
  const StringVector& min_tension() const { return lo_; }
  const StringVector& max_tension() const { return hi_; }

 private:
  enum class Bound : signed char { kFree, kLower, kUpper };
  TensionQpConfig opt_;
  StringVector lo_, hi_;
  std::array<Bound, kSpidarStrings> active_;
  TensionSolution solution_;
};

}  // namespace rheo::drivers
