// rheo::sim: the rheological object of the paper (section 6, eqs. 2-6) on a tetrahedral mesh,
// stepped by the daemon's 1 kHz loop. Build allocates; Step, the force input and the readers
// never allocate.
//
//   auto obj = SimObject::Create(mesh, "soft-jelly");      // allocates
//   obj->SetParameter("k_v", 200.0);                       // validated, wakes the object
//   obj->SetExternalForce(node, {0, -1, 0});               // tool force [N]
//   StepResult r = obj->Step(1e-3);                        // one tick, substeps inside
//   std::span<const Vec3> x = obj->positions();            // for frames
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"
#include "sim/model.h"
#include "sim/params.h"
#include "sim/state.h"

namespace rheo::sim {

/// What one tick did.
struct StepResult {
  int32_t substeps = 0;           // substeps taken (0 when asleep or refused)
  int32_t solver_iterations = 0;  // CG iterations summed over substeps (implicit only)
  double solver_residual = 0.0;   // last relative CG residual (implicit only)
  bool sleeping = false;          // the object was at rest and the tick did no work
  bool restored = false;          // non-finite or exploding state found; last good state restored
  bool substeps_capped = false;   // explicit stability asked for more than max_substeps
  bool invalid_dt = false;        // dt was not finite and positive; nothing was done
};

/// Counters of events since the object was built.
struct EventCounts {
  int64_t steps = 0;
  int64_t substeps = 0;
  int64_t restores = 0;      // recoveries from a non-finite or exploding state
  int64_t shape_resets = 0;  // restores whose last good state blew up again: back to rest shape
  int64_t capped_ticks = 0;  // ticks that hit max_substeps
  int64_t sleeping_ticks = 0;
  int64_t wakes = 0;
};

/// Read on demand (costs one pass over the object).
struct Diagnostics {
  double time = 0.0;                   // [s]
  double volume = 0.0;                 // enclosed by the surface [m^3]
  double rest_volume = 0.0;            // [m^3]
  double kinetic_energy = 0.0;         // [J]
  double gravity_energy = 0.0;         // m g y summed, relative to y = 0 [J]
  double elastic_energy = 0.0;         // Voigt springs + global volume condition [J]
  double potential_energy = 0.0;       // gravity + elastic [J]
  double lowest_point = 0.0;           // smallest node y [m]
  double max_displacement = 0.0;       // largest |x - rest position| [m]
  double max_speed = 0.0;              // [m/s]
  Vec3 floor_force = Vec3::Zero();     // total floor reaction during the last tick [N]
  Vec3 external_force = Vec3::Zero();  // total tool force applied [N]
  bool finite = true;
};

/// The implicit integrator's treatment of the shape springs (eqs. 5-6): all explicit, the
/// stiffest tets in the linear system and the rest explicit, or all in the linear system.
enum class ShapeTreatment { kExplicit, kSplit, kImplicit };

/// A parameter set with what it implies for one object's steps: the explicit step bound and the
/// implicit integrator's shape-spring treatment at its substep. SimObject::Prepare computes it
/// (passes over every element; allocates) so that the thread that steps the object only copies
/// it in (SetParameters(PreparedParameters&)).
struct PreparedParameters {
  Parameters params;
  double h_stable = 0.0;  // explicit stability bound on the substep [s]
  double shape_h = -1.0;  // substep the shape treatment was decided for [s]; -1: not decided
  ShapeTreatment shape = ShapeTreatment::kImplicit;
  int32_t implicit_tets = 0;
  std::vector<uint8_t> tet_implicit;  // per tet, 1 in the linear system (kSplit)
};

class Patch;

class SimObject {
 public:
  /// Builds model and state from a mesh (allocates). Fails on a bad mesh or parameters.
  static Result<std::unique_ptr<SimObject>> Create(const TetMesh& mesh, const Parameters& params,
                                                   Integrator integrator);
  static Result<std::unique_ptr<SimObject>> Create(const TetMesh& mesh, std::string_view preset);
  /// From a prebuilt model (e.g. BuildModelFromParts); masses are taken from the model.
  static Result<std::unique_ptr<SimObject>> Create(Model model, const Parameters& params,
                                                   Integrator integrator);

  /// Sets one parameter by name, validated (INVALID_ARGUMENT names it and its range). Takes
  /// effect on the next Step and wakes the object. Does not allocate.
  Status SetParameter(std::string_view name, double value);
  /// Validates and applies `params`, recomputing what they imply (passes over every element).
  Status SetParameters(const Parameters& params);
  /// What `params` imply for this object stepped with `integrator` at ticks of `dt` (validated;
  /// INVALID_ARGUMENT names a bad parameter). Const, allocates; it may run on another thread
  /// while the object steps: it reads only the topology, the rest shape and the fixed nodes
  /// (do not call SetFixed meanwhile).
  Result<PreparedParameters> Prepare(const Parameters& params, Integrator integrator,
                                     double dt) const;
  /// Applies a prepared set without allocating: its tet flags are swapped in, so `prepared`
  /// keeps the old ones (free it on another thread). A decision for another substep than the
  /// next Step's is redone there.
  Status SetParameters(PreparedParameters& prepared);
  void SetIntegrator(Integrator integrator);

  /// Advances one tick of dt seconds (substeps inside). Never allocates.
  StepResult Step(double dt);

  /// Tool force on one node [N], held until changed. Out-of-range nodes, non-finite values and a
  /// negative stiffness are ignored (returns false). A non-zero force wakes the object.
  /// `stiffness` [N/m] is the force's isotropic -dF/dx: the node then feels
  /// force + stiffness (x_set - x), a spring about where it was when the force was set, and the
  /// implicit integrators take that spring into their system (a coupling far stiffer than the
  /// object stays stable over a step of many ms: sim/multirate.h). 0: a constant force.
  bool SetExternalForce(int32_t node, const Vec3& force, double stiffness = 0.0);
  void ClearExternalForces();
  /// Holds a node in place (or releases it) at its current position.
  bool SetFixed(int32_t node, bool fixed);
  /// Moves a node to a position with a velocity (e.g. a held node dragged by the tool).
  bool SetNodeState(int32_t node, const Vec3& position, const Vec3& velocity);
  /// Rigidly translates the object and zeroes velocities (e.g. drop height).
  void Translate(const Vec3& offset);
  /// Back to the rest shape, zero velocity, rest Voigt ratios.
  void Reset();
  void Wake();

  std::span<const Vec3> positions() const { return state_.x; }
  std::span<const Vec3> velocities() const { return state_.v; }
  std::span<const double> voigt_ratios() const { return state_.a; }
  std::span<const double> edge_tensions() const { return state_.tension; }
  /// Floor force on each node during the last tick [N] (contact reaction).
  std::span<const Vec3> floor_reaction() const { return state_.floor_reaction; }
  const Model& model() const { return model_; }
  /// The whole changing state (like MuJoCo's mjData), for benchmarks and diagnostics.
  const State& state() const { return state_; }
  const Parameters& parameters() const { return params_; }
  Integrator integrator() const { return integrator_; }
  const EventCounts& events() const { return events_; }
  bool sleeping() const { return sleeping_; }
  /// Kinetic energy at the end of the last step [J] (computed in the step's own check pass).
  double kinetic_energy() const { return kinetic_energy_; }
  double time() const { return state_.time; }
  /// Explicit substeps per tick of dt that the stability bound asks for.
  int32_t RequiredSubsteps(double dt) const;
  /// Explicit substeps per tick of dt for a stability bound h_stable [s] (before max_substeps).
  static int32_t RequiredSubsteps(double h_stable, double dt);
  /// Implicit substeps per tick of dt with `p`.
  static int32_t ImplicitSubsteps(const Parameters& p, double dt);
  /// How the implicit integrator treats the shape springs (eqs. 5-6) at substep h (cached per h;
  /// recomputed after parameter changes); with kSplit, shape_implicit_tets() are implicit.
  ShapeTreatment ShapeSpringsTreatment(double h);
  int32_t shape_implicit_tets() const { return shape_implicit_tets_; }

  Diagnostics ComputeDiagnostics() const;

 private:
  friend class Patch;  // copies node and edge state in and out (multirate.h)
  SimObject(Model model, const Parameters& params, Integrator integrator);
  void UpdateDerived();
  // Node masses from unit_mass_ at `density` (no allocation).
  void ApplyDensity(double density);
  // The CG's per-coordinate copies of the node masses and fixed flags (mass3, keep3).
  void SyncNodeArrays();
  // The explicit stability bound on the substep with node masses `mass` [s]; `acc` is scratch
  // (n entries, left zero).
  double StableStep(const Parameters& p, std::span<const double> mass,
                    std::vector<Vec3>& acc) const;
  // The shape springs' treatment at substep h with node masses `mass`: returns it, and fills
  // tet_implicit (kSplit) and implicit_tets. acc (n), rows (4 per tet) and sorted (1 per tet)
  // are scratch.
  ShapeTreatment DecideShape(const Parameters& p, double h, std::span<const double> mass,
                             std::vector<Vec3>& acc, std::vector<double>& rows,
                             std::vector<double>& sorted, std::vector<uint8_t>& tet_implicit,
                             int32_t* implicit_tets) const;
  void SaveGood();
  /// After a teleport, restore, reset, sleep or integrator change.
  void ForgetHistory();
  void RestoreGood();
  // The rest shape, unmoving, moved by `offset`; the history forgotten (Reset and
  // ResetShapeAtGood).
  void PlaceRestShape(const Vec3& offset);
  // The rest shape, unmoving, at the good state's centre of mass (resting on the floor if that
  // put it below): the way out when restoring the good state leads to the same blow-up.
  void ResetShapeAtGood();
  bool CheckState() const;

  Model model_;
  std::vector<double> unit_mass_;  // node mass per unit density [m^3]; fixed after build
  Parameters params_;
  Integrator integrator_;
  State state_;
  double h_stable_ = 0.0;          // explicit stability bound on the substep [s]
  double shape_checked_h_ = -1.0;  // substep ShapeSpringsTreatment last decided for [s]
  ShapeTreatment shape_treatment_ = ShapeTreatment::kImplicit;
  int32_t shape_implicit_tets_ = 0;
  Vec3 placement_ = Vec3::Zero();  // sum of Translate() offsets since build or Reset [m]
  double rest_time_ = 0.0;
  bool sleeping_ = false;
  double kinetic_energy_ = 0.0;  // [J], after the last step
  int32_t steps_since_good_ = 0;
  bool restored_since_good_ = false;  // a restore used the current good state already
  EventCounts events_;
};

}  // namespace rheo::sim
