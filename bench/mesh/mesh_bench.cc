// mesh_bench: (1) our tetrahedra vs TetGen on the same closed surface, (2) a 300-point contour
// to tetrahedra at default resolution, median, (3) time per stage vs contour size.
// Usage: mesh_bench [--sketches DIR] [--tetgen PATH] [--skip-tetgen] [--reps N]
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "mesh/mesh.h"
#include "test_polygons.h"

namespace fs = std::filesystem;
using namespace rheo;
using namespace rheo::mesh;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// CPU time of this thread: robust to other processes sharing the cores [s].
double CpuNow() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

struct TetgenRun {
  bool ok = false;
  int64_t tets = 0;
  double min_dihedral = 0;  // [deg]
  double seconds = 0;       // wall time of the program, including its file I/O [s]
};

// Writes the closed surface as .smesh, runs tetgen, reads .node/.ele back.
TetgenRun RunTetgen(const std::string& tetgen, const TetMesh& m, const std::string& flags,
                    const fs::path& dir, const std::string& name) {
  TetgenRun out;
  const fs::path base = dir / name;
  {
    std::ofstream f(base.string() + ".smesh");
    f.precision(17);
    f << m.positions.size() << " 3 0 0\n";
    for (size_t i = 0; i < m.positions.size(); ++i)
      f << i << ' ' << m.positions[i].x() << ' ' << m.positions[i].y() << ' ' << m.positions[i].z()
        << '\n';
    f << m.surface.size() << " 0\n";
    for (const auto& t : m.surface) f << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
    f << "0\n0\n";
  }
  const std::string cmd =
      tetgen + " -" + flags + " " + base.string() + ".smesh > " + base.string() + ".log 2>&1";
  const double t0 = Now();
  const int rc = std::system(cmd.c_str());
  out.seconds = Now() - t0;
  if (rc != 0) return out;
  std::ifstream nf(base.string() + ".1.node"), ef(base.string() + ".1.ele");
  if (!nf || !ef) return out;
  int64_t nn, dim, na, nb;
  nf >> nn >> dim >> na >> nb;
  std::vector<Vec3> p(nn);
  int64_t first = -1;
  for (int64_t i = 0; i < nn; ++i) {
    int64_t id;
    double x, y, z, skip;
    nf >> id >> x >> y >> z;
    for (int64_t k = 0; k < na + nb; ++k) nf >> skip;
    if (first < 0) first = id;
    p[id - first] = Vec3(x, y, z);
  }
  int64_t ne, npt, ea;
  ef >> ne >> npt >> ea;
  out.min_dihedral = 180;
  for (int64_t i = 0; i < ne; ++i) {
    int64_t id, v[4];
    double skip;
    ef >> id >> v[0] >> v[1] >> v[2] >> v[3];
    for (int64_t k = 0; k < ea; ++k) ef >> skip;
    Vec3 q[4];
    for (int k = 0; k < 4; ++k) q[k] = p[v[k] - first];
    TetMesh one;
    one.positions.assign(q, q + 4);
    const Vec3 a = q[1] - q[0], b = q[2] - q[0], c = q[3] - q[0];
    one.tets = {a.dot(b.cross(c)) > 0 ? std::array<int32_t, 4>{0, 1, 2, 3}
                                      : std::array<int32_t, 4>{1, 0, 2, 3}};
    // Dihedral angles straight from the face normals of this tet.
    const auto& t = one.tets[0];
    const Vec3* P = one.positions.data();
    Vec3 n[4] = {
        (P[t[2]] - P[t[1]]).cross(P[t[3]] - P[t[1]]), (P[t[3]] - P[t[0]]).cross(P[t[2]] - P[t[0]]),
        (P[t[1]] - P[t[0]]).cross(P[t[3]] - P[t[0]]), (P[t[2]] - P[t[0]]).cross(P[t[1]] - P[t[0]])};
    for (auto& x : n) x.normalize();
    for (int i1 = 0; i1 < 4; ++i1)
      for (int i2 = i1 + 1; i2 < 4; ++i2) {
        const double d =
            std::acos(std::clamp(-n[i1].dot(n[i2]), -1.0, 1.0)) * 180 / std::numbers::pi;
        out.min_dihedral = std::min(out.min_dihedral, d);
      }
  }
  out.tets = ne;
  out.ok = true;
  return out;
}

// A wavy ribbon of constant width whose outline has about n points at spacing `step` [px].
Polygon2 Ribbon(int n, double step, double width) {
  const int half = n / 2;
  std::vector<Vec2> center, normal;
  for (int i = 0; i < half; ++i) {
    const double x = i * step;
    const double y = 3 * width * std::sin(x / (6 * width));
    const double dy = 3 * width * std::cos(x / (6 * width)) / (6 * width);
    Vec2 nrm(-dy, 1);
    normal.push_back(nrm.normalized());
    center.emplace_back(x, y);
  }
  Polygon2 p;
  for (int i = 0; i < half; ++i) p.points.push_back(center[i] + 0.5 * width * normal[i]);
  for (int i = half - 1; i >= 0; --i) p.points.push_back(center[i] - 0.5 * width * normal[i]);
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  std::string sketches = RHEO_SKETCH_DIR, tetgen = "tetgen";
  bool skip_tetgen = false;
  int reps = 30;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--sketches" && i + 1 < argc)
      sketches = argv[++i];
    else if (a == "--tetgen" && i + 1 < argc)
      tetgen = argv[++i];
    else if (a == "--skip-tetgen")
      skip_tetgen = true;
    else if (a == "--reps" && i + 1 < argc)
      reps = std::atoi(argv[++i]);
  }
  const MeshOptions opt;

  // (1) Side by side with TetGen.
  std::vector<std::pair<std::string, Polygon2>> cases;
  for (const char* name : testing::kSampleNames) {
    Polygon2 c;
    if (testing::ReadContour(sketches + "/" + name + ".truth.json", c)) cases.emplace_back(name, c);
  }
  if (cases.empty()) cases.emplace_back("ellipse(gen)", testing::Ellipse(200, 120, 300));
  const bool have_tetgen =
      !skip_tetgen && std::system(("command -v " + tetgen + " > /dev/null 2>&1").c_str()) == 0;
  const fs::path dir =
      fs::temp_directory_path() / ("rheo_mesh_bench_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::printf(
      "== Rheo default (columns over a quality 2D mesh), Rheo paper cells (columns over Teddy "
      "rows), TetGen on the default surface ==\n");
  std::printf(
      "resolution %.4f m, pixel size %.2e m/px; TetGen time is the program's wall time "
      "including file I/O\n",
      opt.resolution, opt.pixel_size);
  std::printf("%-9s %6s | %7s %7s %8s %7s | %7s %7s %7s | %7s %7s %8s | %7s %7s %8s\n", "case",
              "faces", "tets", "min_dih", "ms", "minV/md", "paper", "min_dih", "minV/md", "tg-pY",
              "min_dih", "ms", "tg-pq", "min_dih", "ms");
  for (const auto& [name, contour] : cases) {
    std::vector<double> times;
    Result<MeshResult> r = BuildSolid(contour, opt);
    for (int k = 0; k < 10 && r.ok(); ++k) {
      const double t0 = Now();
      r = BuildSolid(contour, opt);
      times.push_back(Now() - t0);
    }
    if (!r.ok()) {
      std::printf("%-9s failed: %s\n", name.c_str(), r.error().message.c_str());
      continue;
    }
    const auto& q = r->quality;
    std::printf("%-9s %6zu | %7lld %7.2f %8.2f %7.3f |", name.c_str(), r->mesh.surface.size(),
                static_cast<long long>(q.num_tets), q.min_dihedral_deg, 1e3 * Median(times),
                q.min_volume_ratio);
    MeshOptions paper = opt;
    paper.division = Division::kPaper;
    auto rp = BuildSolid(contour, paper);
    if (rp.ok())
      std::printf(" %7lld %7.2f %7.3f |", static_cast<long long>(rp->quality.num_tets),
                  rp->quality.min_dihedral_deg, rp->quality.min_volume_ratio);
    else
      std::printf(" %7s %7s %7s |", "fail", "-", "-");
    if (have_tetgen) {
      for (const char* flags : {"pYQ", "pq1.414YQ"}) {
        TetgenRun t = RunTetgen(tetgen, r->mesh, flags, dir, name + "_" + flags);
        if (t.ok)
          std::printf(" %7lld %7.2f %8.2f |", static_cast<long long>(t.tets), t.min_dihedral,
                      1e3 * t.seconds);
        else
          std::printf(" %7s %7s %8s |", "fail", "-", "-");
      }
    } else {
      std::printf(" (tetgen not run)");
    }
    std::printf("\n");
  }
  fs::remove_all(dir);

  // (2) 300-point contour at default resolution.
  {
    std::mt19937 rng(42);
    Polygon2 blob;
    for (int i = 0; i < 300; ++i) {  // a smooth bean-like outline, 512 px scale
      const double t = 2 * std::numbers::pi * i / 300;
      const double r = 170 * (1 + 0.18 * std::cos(2 * t) + 0.08 * std::sin(3 * t));
      blob.points.emplace_back(256 + r * std::cos(t), 256 + 0.75 * r * std::sin(t));
    }
    std::map<std::string, std::vector<double>> stage;
    std::vector<double> total, cpu;
    int64_t tets = 0;
    for (int k = 0; k < reps + 3; ++k) {
      const double t0 = Now(), c0 = CpuNow();
      auto r = BuildSolid(blob, opt);
      const double dt = Now() - t0, dc = CpuNow() - c0;
      if (!r.ok()) {
        std::printf("300-point contour failed: %s\n", r.error().message.c_str());
        return 1;
      }
      if (k < 3) continue;  // warm-up
      total.push_back(dt);
      cpu.push_back(dc);
      tets = r->quality.num_tets;
      for (const auto& s : r->timings) stage[s.stage].push_back(s.seconds);
    }
    std::printf("\n== 300-point contour -> tetrahedra, default resolution, %d runs ==\n", reps);
    std::printf("tets %lld; median wall %.2f ms, median thread CPU %.2f ms (target <= 20 ms)\n",
                static_cast<long long>(tets), 1e3 * Median(total), 1e3 * Median(cpu));
    for (const auto& [s, v] : stage) std::printf("  %-11s %8.3f ms\n", s.c_str(), 1e3 * Median(v));
  }

  // (3) Time per stage vs contour size: a ribbon whose area (and so mesh) grows linearly with n.
  {
    std::printf(
        "\n== Time per stage vs contour size (wavy ribbon, 8 px spacing, resolution 2 mm) ==\n");
    std::printf(
        "fastest of 5-15 runs [ms]; time / (n log2 n) normalised to n = 100 in brackets; <= ~1 "
        "means n log n or better\n");
    MeshOptions o;
    o.resolution = 0.002;  // 8 px at the default pixel size: the outline keeps its n points
    const char* stages[] = {"contour", "cdt",        "teddy",  "mesh2d",
                            "inflate", "tetrahedra", "quality"};
    std::printf("%6s %8s", "n", "tets");
    for (const char* s : stages) std::printf(" %16s", s);
    std::printf(" %16s\n", "total");
    std::map<std::string, double> base;
    std::map<std::string, std::vector<std::pair<double, double>>> fit;  // (log n, log ms)
    for (int n : {100, 200, 400, 800, 1600, 3000}) {
      const Polygon2 rib = Ribbon(n, 8.0, 40.0);
      std::map<std::string, std::vector<double>> st;
      int64_t tets = 0;
      const int runs = n <= 400 ? 15 : n <= 1600 ? 7 : 5;
      for (int k = 0; k < runs; ++k) {
        auto r = BuildSolid(rib, o);
        if (!r.ok()) {
          std::printf("n=%d failed: %s\n", n, r.error().message.c_str());
          return 1;
        }
        tets = r->quality.num_tets;
        double tot = 0;
        for (const auto& s : r->timings) st[s.stage].push_back(s.seconds), tot += s.seconds;
        st["total"].push_back(tot);
      }
      const double nlogn = n * std::log2(static_cast<double>(n));
      std::printf("%6d %8lld", n, static_cast<long long>(tets));
      for (const char* s :
           {"contour", "cdt", "teddy", "mesh2d", "inflate", "tetrahedra", "quality", "total"}) {
        // Fastest run: the machine is shared, and interference only ever adds time.
        const double ms = 1e3 * *std::min_element(st[s].begin(), st[s].end());
        if (n == 100) base[s] = ms / nlogn;
        fit[s].emplace_back(std::log(static_cast<double>(n)), std::log(std::max(ms, 1e-6)));
        std::printf(" %8.3f [%5.2f]", ms, base[s] > 0 ? ms / nlogn / base[s] : 0.0);
      }
      std::printf("\n");
    }
    // Least-squares slope of log(time) on log(n): n log n over 100..3000 fits about 1.1-1.15.
    std::printf("%6s %8s", "slope", "");
    for (const char* s :
         {"contour", "cdt", "teddy", "mesh2d", "inflate", "tetrahedra", "quality", "total"}) {
      const auto& v = fit[s];
      double mx = 0, my = 0, sxx = 0, sxy = 0;
      for (auto [x, y] : v) mx += x / v.size(), my += y / v.size();
      for (auto [x, y] : v) sxx += (x - mx) * (x - mx), sxy += (x - mx) * (y - my);
      std::printf(" %16.2f", sxx > 0 ? sxy / sxx : 0.0);
    }
    std::printf("\n");
  }
  return 0;
}
