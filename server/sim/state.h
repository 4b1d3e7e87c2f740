// The changing part of a simulated object (like MuJoCo's mjData): allocated once when the object
// is built, then only overwritten, so a step never allocates.
#pragma once

#include <cstdint>
#include <vector>

#include "common/geometry.h"
#include "sim/model.h"

namespace rheo::sim {

struct State {
  double time = 0.0;            // simulated time [s]
  std::vector<Vec3> x;          // node positions (n) [m]
  std::vector<Vec3> v;          // node velocities (n) [m/s]
  std::vector<double> a;        // Voigt length ratio per edge (e) [-]
  std::vector<double> tension;  // last tension per edge, drives eq. 3 (e) [N]

  std::vector<Vec3> f_ext;  // external (tool) force per node (n) [N]
  // Its stiffness: the external force on node i is f_ext + k_ext (x_ext - x), a spring about the
  // position x_ext it was set at, taken into the implicit system (so a stiff tool coupling stays
  // stable over a long step). ext_springs counts the nodes with k_ext > 0; with none the
  // integrators do not look at these.
  std::vector<double> k_ext;  // (n) [N/m]
  std::vector<Vec3> x_ext;    // (n) [m]
  int32_t ext_springs = 0;
  std::vector<double> sys_mass3;  // mass3 + hh^2 k_ext for the substep, when ext_springs (3n) [kg]
  std::vector<Vec3> floor_reaction;  // floor force on each node during the last tick (n) [N]

  // Scratch, sized once.
  std::vector<Vec3> f;            // force accumulator (n) [N]
  std::vector<Vec3> vol_grad;     // gradient of the enclosed volume per node (n) [m^2]
  std::vector<double> damp_diag;  // sum of the edge damping coefficients at each node (n) [N s/m]
  // Per-edge linearisation for the implicit integrator. The system is A = M + h D + h^2 K on the
  // velocity change [m/s], so every block and coefficient of it is a mass: h^2 times a stiffness
  // [N/m] and h times a viscosity [N s/m] are both [N s^2/m] = [kg]. edge_e* and edge_axial_c
  // hold whole groups of kEdgeBlock edges (forces.h), zero past the last edge.
  std::vector<double> edge_ex, edge_ey, edge_ez;  // unit edge vectors (e) [-]
  std::vector<double> edge_axial_k;               // h^2 k_eff along the edge (e) [N s^2/m = kg]
  std::vector<double> edge_axial_c;               // h c_eff along the edge (e) [N s^2/m = kg]
  std::vector<double> edge_lateral;  // h^2 max(T,0)/l across the edge (e) [N s^2/m = kg]
  // Per edge, its 3x3 block of the system with the shape springs' blocks added, in groups of
  // kEdgeBlock edges (forces.h); empty without model.edge_tet.
  std::vector<float> edge_block;
  // What edge_block was assembled for (Parameters::jacobian_lag): the substeps since (-1: not
  // assembled, or no longer valid), and the step and the count of elements in the system then.
  int32_t edge_block_age = -1;
  double edge_block_hh = 0.0;
  int64_t edge_block_elements = 0;
  std::vector<double> shape_coef;  // h^2 sigma per face, sigma [N/m] (k) [N s^2/m = kg]
  std::vector<Vec3> shape_dir;     // force directions, 3 per face (3k) [-]
  std::vector<float> tet_w;        // the same per tet, 12 in a row: [12 tet + 3 q + c] (12m) [-]
  std::vector<double> tet_coef;    // h^2 sigma per tet, sigma [N/m] (m) [N s^2/m = kg]
  // Per-tet split of the shape springs between the linear system and the explicit forces.
  bool tet_split = false;          // tet_implicit decides; else all tets alike
  int64_t system_elements = 0;     // tets and faces whose blocks are in the system
  int32_t last_cg_iterations = 0;  // of the last implicit substep
  // Running mean of the implicit substeps' CG iterations (0: none yet, taken as 8), for
  // Parameters::cg_iteration_budget.
  double cg_mean_iterations = 0.0;
  std::vector<uint8_t> tet_implicit;  // 1 = in the linear system (m)
  std::vector<double> tet_stiffness;  // scratch for the split's bisection (m)
  std::vector<double> tet_rows;       // scratch: each tet's share of its nodes' row sums (4m)
  std::vector<Vec3> f_tet_implicit;   // the implicit tets' share of f (n) [N]
  double global_k = 0.0;  // h^2 K of the rank-one volume term, K [N/m^5] [N s^2/m^5 = kg/m^4]
  double global_c = 0.0;  // h C of the rank-one volume term, C [N s/m^5] [N s^2/m^5 = kg/m^4]
  // Added to the volume the faces enclose (eq. 4): a patch's faces are part of a whole's surface,
  // and this is the rest of the whole's volume (sim/multirate.h). 0 for a whole object [m^3].
  double volume_offset = 0.0;
  std::vector<Vec3> cg_r, cg_z, cg_p, cg_q;  // CG vectors (n)
  std::vector<Vec3> dv;       // the substep's velocity change, CG's unknown (n) [m/s]
  std::vector<Vec3> dv_prev;  // dv one substep back (n) [m/s]
  std::vector<double> diag;   // diagonal of the implicit system, for its preconditioner (n) [kg]
  std::vector<double> inv_diag3;  // its inverse, 0 on fixed nodes, per coordinate (3n) [1/kg]
  // The 3x3 block Jacobi preconditioner (Parameters::cg_preconditioner): each node's block of
  // the system inverted, symmetric, as six arrays of n (xx, yy, zz, xy, xz, yz) [1/kg]; zero on
  // fixed nodes and in the rows and columns of the coordinates the floor holds.
  std::vector<double> pre_block;
  std::vector<double> mass3;  // node masses per coordinate (3n) [kg]
  std::vector<double> keep3;  // 1 per coordinate of a free node, 0 of a fixed one (3n)
  // The floor inside the implicit solve: per node, the impulse the floor gave it in the last
  // substep's solve (zero where the floor took no part; y > 0 keeps it held in the next one; x
  // and z are the static friction of a sticking node) (n) [N s]; floor_stick: 1 where the node
  // sticks (its tangential velocity is held at 0 in the next solve) (n); floor_nodes counts the
  // nodes the floor held.
  std::vector<Vec3> floor_impulse;
  std::vector<uint8_t> floor_stick;
  int32_t floor_nodes = 0;

  // History of the implicit integrator (BDF2): positions and velocities one substep back.
  std::vector<Vec3> x_prev, v_prev;  // [m], [m/s]
  bool have_prev = false;  // false after anything that breaks the history (restore, teleport)
  double prev_h = 0.0;     // the substep that produced the current state [s]
  std::vector<Vec3> f_shape, f_shape_prev;  // explicit shape spring forces, now and one back [N]
  bool have_prev_shape = false;

  // Last good state for recovery.
  std::vector<Vec3> good_x, good_v;
  std::vector<double> good_a, good_tension;
  double good_time = 0.0;
};

/// Sizes every array for `model` and sets the rest state.
void InitState(const Model& model, double voigt_ratio, State& state);

}  // namespace rheo::sim
