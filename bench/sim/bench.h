// sim_bench: what the modes share (timing, the test meshes, the integrators as the benches name
// them, the work-precision scenes and their reference runs) and the modes themselves, one file
// each. Measured, not asserted; one thread throughout (the library has none).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "samples.h"
#include "sim/sim.h"

namespace sim_bench {

using rheo::Result;
using rheo::TetMesh;
using rheo::Vec3;
using namespace rheo::sim;

// The calling thread's CPU time [s].
double CpuSeconds();

double Median(std::vector<double> v);
double Percentile(std::vector<double> v, double q);

// A 10 cm x 6 cm x 8 cm box with about `tets` tetrahedra.
TetMesh BoxWithTets(int tets);

// A box of the 10:6:8 shape with about `tets` tetrahedra in cells of edge `cell` [m]: the object
// grows with the count, the element size (and so the stiffness per mass) stays.
TetMesh BoxWithCell(int tets, double cell);

// An integrator as the benches name it: the scheme plus the implicit-damping switch.
struct Method {
  const char* name;
  Integrator integrator;
  double implicit_damping;
  double implicit_order;
  void Apply(Parameters& p) const {
    p.implicit_damping = implicit_damping;
    p.implicit_order = implicit_order;
  }
};
inline constexpr Method kMethods[] = {
    {"symplectic-euler", Integrator::kSymplecticEuler, 0.0, 2.0},
    {"symplectic+impl.damping", Integrator::kSymplecticEuler, 1.0, 2.0},
    {"implicit BDF1 (order 1)", Integrator::kImplicitEuler, 0.0, 1.0},
    {"implicit BDF2 (default)", Integrator::kImplicitEuler, 0.0, 2.0},
};

// Scenes for work-precision: the same mesh and parameters, 0.5 s.
struct Scene {
  const char* name;
  TetMesh mesh;
  Parameters params;
  double drop = 0.0;         // lowest point above the floor at t = 0 [m]
  double press_force = 0.0;  // total downward force on the top nodes, ramped over 0.1 s [N]
};

std::vector<Scene> Scenes();
// The scenes of precision-sizes (and trace) on `mesh`: a 2 cm drop and a 3 N press.
std::vector<Scene> SizeScenes(const TetMesh& mesh, const Parameters& p);

struct RunResult {
  std::vector<Vec3> x;
  double cpu = 0.0;  // [s]
  int64_t substeps = 0;
  int64_t restores = 0;
  int64_t iterations = 0;       // CG iterations
  int32_t max_iterations = 0;   // the most CG iterations in one tick
  std::vector<double> tick_us;  // each tick's CPU time [us]
};

// The scene's pressed nodes (those within 1 cm of the top), and the press at tick k of dt: the
// scene's force ramped over 0.1 s, shared among them (nothing in a drop).
std::vector<int32_t> TopNodes(const SimObject& s);
void ApplyPress(SimObject& s, const Scene& sc, std::span<const int32_t> top, int64_t k, double dt);

RunResult RunScene(const Scene& sc, const Method& method, double dt, double t_end,
                   double cg_tol = -1.0);

double RmsError(const std::vector<Vec3>& a, const std::vector<Vec3>& b, double size);
// RMS distance of `x` from `ref` after the best rigid fit of one onto the other, over `size`.
double ShapeError(const std::vector<Vec3>& ref, const std::vector<Vec3>& x, double size);

// The modes (main.cc maps the command line onto them); each returns the exit status.
int Speed(int max_tets);                                 // speed.cc
int Kernels(int target, const std::string& sample);      // kernels.cc (sample empty: the box)
int Preconditioners(int max_tets);                       // precond.cc
int Precision(const std::string& svg);                   // precision.cc
int ParameterChange();                                   // params.cc
int CgSweep();                                           // cg.cc
int Sketched(const std::string& sample, int max_tets);   // sketched.cc
int Budget(const std::string& sample, int max_tets);     // budget.cc
int MultiRate(const std::string& sample, int max_tets);  // multirate.cc
// Work-precision at each size of a sample (precision.cc): a table and one SVG per size.
int PrecisionSizes(const std::string& sample, int max_tets, const std::string& svg_prefix);
int Trace(const std::string& sample, int max_tets, const std::string& scene,
          std::span<char* const> sets);
#ifdef RHEO_HAVE_BULLET
int Bullet();       // bullet.cc
int BulletCheck();  // bullet.cc
// btSoftBody on `sc`'s tetrahedra (4 position iterations, link stiffness kLST; `bending` > 0 adds
// links between nodes that many links apart, as generateBendingConstraints), its step times.
struct BulletRun {
  std::vector<Vec3> x;
  double cpu = 0.0;
  std::vector<double> tick_us;
};
BulletRun RunBullet(const Scene& sc, double dt, double t_end, double stiffness, int bending = 2);
#endif

}  // namespace sim_bench
