// sim_bench precision [svg_path]: work-precision, CPU time per simulated second vs error (table +
// SVG).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "bench.h"

namespace sim_bench {
namespace {

struct Point {
  std::string scene, integrator;
  double dt, error, cpu_per_s;
};

void WriteSvg(const std::vector<Point>& pts, const std::string& path) {
  // Log-log: x = error, y = CPU seconds per simulated second.
  const double W = 720, H = 480, L = 80, R = 200, T = 30, B = 60;
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
  f << "<text x='" << (L + W - R) / 2 - 100 << "' y='" << H - 20
    << "'>error: RMS node distance to reference at 0.5 s / size</text>\n";
  f << "<text x='15' y='" << T + 10 << "'>CPU s per simulated s</text>\n";
  const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
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
        << colors[si % 6] << "'/>\n";
    }
    f << "<polyline points='" << poly << "' fill='none' stroke='" << colors[si % 6] << "'/>\n";
    f << "<text x='" << W - R + 10 << "' y='" << T + 20 + 18 * si << "' fill='" << colors[si % 6]
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
