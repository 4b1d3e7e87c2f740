// sim_bench: the helpers the modes share.
#include <algorithm>
#include <cmath>
#include <ctime>

#include "bench.h"
#include "sim/deformation.h"
#include "sim/primitives.h"

namespace sim_bench {

double CpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}
double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
}

TetMesh BoxWithTets(int tets) {
  const double cells = tets / 6.0;
  const double s = std::cbrt(cells / (1.0 * 0.6 * 0.8));
  const int nx = std::max(1, static_cast<int>(std::lround(s)));
  const int ny = std::max(1, static_cast<int>(std::lround(0.6 * s)));
  const int nz = std::max(1, static_cast<int>(std::lround(0.8 * s)));
  return *MakeBoxTetMesh(nx, ny, nz, Vec3(0.1, 0.06, 0.08));
}

TetMesh BoxWithCell(int tets, double cell) {
  const double s = std::cbrt(tets / 6.0 / (1.0 * 0.6 * 0.8));
  const int nx = std::max(1, static_cast<int>(std::lround(s)));
  const int ny = std::max(1, static_cast<int>(std::lround(0.6 * s)));
  const int nz = std::max(1, static_cast<int>(std::lround(0.8 * s)));
  return *MakeBoxTetMesh(nx, ny, nz, cell * Vec3(nx, ny, nz));
}

std::vector<Scene> Scenes() {
  std::vector<Scene> out;
  const TetMesh blob = *MakeEllipsoidTetMesh(4, Vec3(0.05, 0.035, 0.04), Vec3(0, 0.035, 0));
  Parameters p = FindPreset("organ")->params;
  p.sleep_time = 0.0;
  out.push_back({"drop", blob, p, 0.05, 0.0});
  out.push_back({"press", blob, p, 0.0, 3.0});
  return out;
}

std::vector<Scene> SizeScenes(const TetMesh& mesh, const Parameters& p) {
  return {Scene{"drop", mesh, p, 0.02, 0.0}, Scene{"press", mesh, p, 0.0, 3.0}};
}

std::vector<int32_t> TopNodes(const SimObject& s) {
  std::vector<int32_t> top;
  double y_max = -1e30;
  for (const Vec3& x : s.positions()) y_max = std::max(y_max, x.y());
  for (int32_t i = 0; i < s.model().num_nodes; ++i)
    if (s.positions()[i].y() > y_max - 0.01) top.push_back(i);
  return top;
}

void ApplyPress(SimObject& s, const Scene& sc, std::span<const int32_t> top, int64_t k, double dt) {
  if (!(sc.press_force > 0) || top.empty()) return;
  const double ramp = std::min(1.0, (k * dt) / 0.1);
  for (int32_t i : top) s.SetExternalForce(i, Vec3(0, -ramp * sc.press_force / top.size(), 0));
}

RunResult RunScene(const Scene& sc, const Method& method, double dt, double t_end, double cg_tol) {
  const Integrator integ = method.integrator;
  Parameters p = sc.params;
  method.Apply(p);
  if (cg_tol > 0) p.cg_tolerance = cg_tol;
  p.max_substeps = 10000;
  auto obj = SimObject::Create(sc.mesh, p, integ);
  SimObject& s = **obj;
  s.Translate(Vec3(0, sc.drop, 0));
  const std::vector<int32_t> top = TopNodes(s);
  RunResult r;
  const int64_t ticks = std::llround(t_end / dt);
  const double t0 = CpuSeconds();
  for (int64_t k = 0; k < ticks; ++k) {
    ApplyPress(s, sc, top, k, dt);
    const double c0 = CpuSeconds();
    const StepResult st = s.Step(dt);
    r.tick_us.push_back((CpuSeconds() - c0) * 1e6);
    r.substeps += st.substeps;
    r.restores += st.restored;
    r.iterations += st.solver_iterations;
    r.max_iterations = std::max(r.max_iterations, st.solver_iterations);
  }
  r.cpu = CpuSeconds() - t0;
  r.x.assign(s.positions().begin(), s.positions().end());
  return r;
}

double ShapeError(const std::vector<Vec3>& ref, const std::vector<Vec3>& x, double size) {
  return rheo::sim::MeasureShapeChange(ref, x, Vec3(0, 1, 0)).rms / size;
}

double RmsError(const std::vector<Vec3>& a, const std::vector<Vec3>& b, double size) {
  double sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]).squaredNorm();
  return std::sqrt(sum / a.size()) / size;
}

}  // namespace sim_bench
