// The loop's cost model on this machine: what a tick of each object costs, measured at start-up
// (sim::PredictTickCost's coefficients), and the share of the tick the simulation may take.
#pragma once

#include "sim/cost.h"

namespace rheo::daemon {

/// Steps a generated block of about 1,000 tetrahedra off the loop (symplectic Euler, then the
/// implicit integrator at two fixed CG iteration counts, then again with every tetrahedron's
/// shape springs in the linear system) and returns the time per element of a substep and of a
/// CG iteration, and per system tetrahedron: the fastest of 40 ticks of each, about 60 ms.
sim::CostCoefficients MeasureTickCost();

}  // namespace rheo::daemon
