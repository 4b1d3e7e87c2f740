// sim_bench precision [svg_path]: work-precision, CPU time per simulated second vs error (table +
// SVG).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "bench.h"
#include "sim/deformation.h"

namespace sim_bench {
namespace {

struct Point {
  std::string scene, integrator;
  double dt, error, cpu_per_s;
};

void WriteSvg(const std::vector<Point>& pts, const std::string& path,
              const std::string& xlabel = "error: RMS node distance to reference at 0.5 s / size") {
  // Log-log: x = error, y = CPU seconds per simulated second.
  const double W = 780, H = 480, L = 80, R = 260, T = 30, B = 60;
  double ex0 = 1e-6, ex1 = 1.0, ey0 = 1e-3, ey1 = 100.0;
  auto X = [&](double e) {
    return L + (std::log10(std::max(e, ex0)) - std::log10(ex0)) /
                   (std::log10(ex1) - std::log10(ex0)) * (W - L - R);
  };
  auto Y = [&](double c) {
    return H - B -
           (std::log10(std::max(c, ey0)) - std::log10(ey0)) / (std::log10(ey1) - std::log10(ey0)) *
               (H - T - B);
  };
  std::ofstream f(path);
  f << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
    << "' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' "
       "fill='white'/>\n";
  for (int d = -6; d <= 0; ++d) {
    const double x = X(std::pow(10.0, d));
    f << "<line x1='" << x << "' y1='" << T << "' x2='" << x << "' y2='" << H - B
      << "' stroke='#ddd'/><text x='" << x - 12 << "' y='" << H - B + 18 << "'>1e" << d
      << "</text>\n";
  }
  for (int d = -3; d <= 2; ++d) {
    const double y = Y(std::pow(10.0, d));
    f << "<line x1='" << L << "' y1='" << y << "' x2='" << W - R << "' y2='" << y
      << "' stroke='#ddd'/><text x='" << L - 40 << "' y='" << y + 4 << "'>1e" << d << "</text>\n";
  }
  // Real-time budget: 1 s of CPU per simulated second; target error 1 %.
  f << "<line x1='" << L << "' y1='" << Y(1.0) << "' x2='" << W - R << "' y2='" << Y(1.0)
    << "' stroke='red' stroke-dasharray='4'/>\n";
  f << "<line x1='" << X(0.01) << "' y1='" << T << "' x2='" << X(0.01) << "' y2='" << H - B
    << "' stroke='red' stroke-dasharray='4'/>\n";
  f << "<text x='" << (L + W - R) / 2 - 100 << "' y='" << H - 20 << "'>" << xlabel << "</text>\n";
  // Vertical, beside the tick labels (across the top it ran into the "1e2" label).
  f << "<text transform='translate(20," << (T + H - B) / 2
    << ") rotate(-90)' text-anchor='middle'>CPU s per simulated s</text>\n";
  const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd",
                          "#ff7f0e", "#8c564b", "#e377c2", "#17becf"};
  std::vector<std::string> series;
  for (const Point& p : pts) {
    const std::string key = p.scene + " " + p.integrator;
    if (std::find(series.begin(), series.end(), key) == series.end()) series.push_back(key);
  }
  for (size_t si = 0; si < series.size(); ++si) {
    std::string poly;
    for (const Point& p : pts) {
      if (p.scene + " " + p.integrator != series[si]) continue;
      poly += std::to_string(X(p.error)) + "," + std::to_string(Y(p.cpu_per_s)) + " ";
      f << "<circle cx='" << X(p.error) << "' cy='" << Y(p.cpu_per_s) << "' r='3' fill='"
        << colors[si % 8] << "'/>\n";
    }
    f << "<polyline points='" << poly << "' fill='none' stroke='" << colors[si % 8] << "'/>\n";
    f << "<text x='" << W - R + 10 << "' y='" << T + 20 + 18 * si << "' fill='" << colors[si % 8]
      << "'>" << series[si] << "</text>\n";
  }
  f << "</svg>\n";
}

}  // namespace

int Precision(const std::string& svg) {
  const double t_end = 0.5;
  std::vector<Point> pts;
  std::printf(
      "# work-precision: error = RMS(x - x_ref)/size at t = 0.5 s; reference = "
      "symplectic Euler, tick 1e-5 s\n");
  std::printf("%-6s %-24s %9s %9s %12s %10s %8s\n", "scene", "integrator", "dt_s", "substep_s",
              "error", "cpu_s/s", "restores");
  for (const Scene& sc : Scenes()) {
    const RunResult ref = RunScene(sc, kMethods[0], 1e-5, t_end);
    const double size =
        (**SimObject::Create(sc.mesh, sc.params, Integrator::kSymplecticEuler)).model().size;
    for (const Method& method : kMethods) {
      for (double dt : {4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4}) {
        const RunResult r = RunScene(sc, method, dt, t_end);
        const double err = RmsError(r.x, ref.x, size);
        const double ticks = std::llround(t_end / dt);
        pts.push_back({sc.name, method.name, dt, err, r.cpu / t_end});
        std::printf("%-6s %-24s %9.2e %9.2e %12.3e %10.4f %8lld\n", sc.name, method.name, dt,
                    dt * ticks / r.substeps, err, r.cpu / t_end,
                    static_cast<long long>(r.restores));
      }
    }
  }
  // The goal: error <= 1 % within the real-time budget (at most 1 CPU second per simulated second;
  // a tick of 1 ms split into 1 ms / dt substeps gives the same run).
  std::printf(
      "# within the real-time budget (cpu_s/s <= 1): the smallest error of each integrator\n");
  for (const Scene& sc : Scenes()) {
    for (const Method& method : kMethods) {
      const Point* best = nullptr;
      for (const Point& p : pts) {
        if (p.scene == sc.name && p.integrator == method.name && p.cpu_per_s <= 1.0 &&
            (best == nullptr || p.error < best->error))
          best = &p;
      }
      if (best != nullptr) {
        std::printf("#   %-6s %-24s dt %.2e: error %.3e at %.3f cpu_s/s%s\n", sc.name, method.name,
                    best->dt, best->error, best->cpu_per_s, best->error <= 0.01 ? " (<= 1 %)" : "");
      } else {
        std::printf("#   %-6s %-24s none within the budget\n", sc.name, method.name);
      }
    }
  }
  if (!svg.empty()) {
    WriteSvg(pts, svg);
    std::printf("# plot written to %s\n", svg.c_str());
  }
  return 0;
}

}  // namespace sim_bench

namespace sim_bench {

int PrecisionSizes(const std::string& sample, int max_tets, const std::string& svg_prefix) {
  auto meshes = MeshSampleSizes(sample, max_tets);
  if (!meshes.ok()) {
    std::fprintf(stderr, "sim_bench precision-sizes: %s\n", meshes.error().message.c_str());
    return 1;
  }
  const double t_end = 0.3, ref_dt = 1.25e-4;
  std::printf(
      "# work-precision per size: samples/%s.json meshed at about 5k/20k/100k tets, organ preset, "
      "0.3 s;\n# drop = 2 cm onto the floor, press = 3 N ramped over 0.1 s on the top nodes of "
      "the object resting on it.\n# pos_err = RMS(x - x_ref)/size at 0.3 s (a bean rolls: it "
      "counts the roll); shape_err (plotted) = the same after the best rigid\n# fit of x onto "
      "x_ref (sim::MeasureShapeChange); size = the rest shape's bounding-box diagonal; "
      "reference = implicit BDF2\n# at %.3g s ticks. Bullet: "
      "btSoftBody on the same tetrahedra, 4 position iterations, kLST 1, the tets' links\n# "
      "only. One thread.\n",
      sample.c_str(), ref_dt);
  std::printf("%-6s %7s %-24s %9s %12s %12s %10s %10s %8s\n", "scene", "tets", "integrator", "dt_s",
              "shape_err", "pos_err", "cpu_s/s", "cpu_us", "restores");
  const Method* methods[] = {&kMethods[1], &kMethods[2], &kMethods[3]};
  for (size_t mi = 0; mi < meshes->meshes.size(); ++mi) {
    const TetMesh& mesh = meshes->meshes[mi];
    Parameters p = FindPreset("organ")->params;
    p.sleep_time = 0.0;
    std::vector<Point> pts;
    for (const Scene& sc : SizeScenes(mesh, p)) {
      const RunResult ref = RunScene(sc, kMethods[3], ref_dt, t_end);
      const double size =
          (**SimObject::Create(sc.mesh, sc.params, Integrator::kImplicitEuler)).model().size;
      std::printf("# %s %zu tets: reference %lld restores, %.1f s of CPU\n", sc.name,
                  mesh.tets.size(), static_cast<long long>(ref.restores), ref.cpu);
      for (const Method* method : methods) {
        for (double dt : {2e-3, 1e-3, 5e-4}) {
          // Symplectic Euler's substeps follow its stability bound, not dt: one tick is enough.
          if (method->integrator == Integrator::kSymplecticEuler && dt != 1e-3) continue;
          const RunResult r = RunScene(sc, *method, dt, t_end);
          const double err = RmsError(r.x, ref.x, size);
          const double shape = ShapeError(ref.x, r.x, size);
          const double ticks = std::round(t_end / dt);
          pts.push_back({sc.name, method->name, dt, shape, r.cpu / t_end});
          std::printf("%-6s %7zu %-24s %9.2e %12.3e %12.3e %10.4f %10.1f %8lld\n", sc.name,
                      mesh.tets.size(), method->name, dt, shape, err, r.cpu / t_end,
                      r.cpu / ticks * 1e6, static_cast<long long>(r.restores));
          std::fflush(stdout);
        }
      }
#ifdef RHEO_HAVE_BULLET
      for (double dt : {2e-3, 1e-3, 5e-4}) {
        const BulletRun b = RunBullet(sc, dt, t_end, 1.0, 0);
        const double err = RmsError(b.x, ref.x, size);
        const double shape = ShapeError(ref.x, b.x, size);
        pts.push_back({sc.name, "bullet btSoftBody", dt, shape, b.cpu / t_end});
        std::printf("%-6s %7zu %-24s %9.2e %12.3e %12.3e %10.4f %10.1f %8s\n", sc.name,
                    mesh.tets.size(), "bullet btSoftBody", dt, shape, err, b.cpu / t_end,
                    b.cpu / std::round(t_end / dt) * 1e6, "-");
        std::fflush(stdout);
      }
#endif
    }
    if (!svg_prefix.empty()) {
      const std::string path = svg_prefix + "_" + std::to_string(mesh.tets.size()) + ".svg";
      WriteSvg(pts, path,
               "shape error at 0.3 s (rigid motion removed) / size, " +
                   std::to_string(mesh.tets.size()) + " tets");
      std::printf("# plot written to %s\n", path.c_str());
    }
  }
  std::printf(
      "# cpu_s/s <= 1: within real time on one core (the loop's simulation budget is 0.6 of it); "
      "cpu_us: CPU per tick.\n");
  return 0;
}

}  // namespace sim_bench
