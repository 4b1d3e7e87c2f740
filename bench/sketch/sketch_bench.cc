// Per-stage timings (median of repeated runs) of the contour extraction. Prints a table.
//   sketch_bench [repeats]
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "sketch/sketch.h"
#include "test_util.h"

namespace {

using rheo::Vec2;
using rheo::sketch::ContourOptions;
using rheo::sketch::ContourResult;

// CPU time of this thread [ms]: on a shared, loaded machine wall time overstates the work.
double CpuMs() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

struct Case {
  std::string name;
  std::vector<uint8_t> bytes;
  double target_ms;  // 0: none
};

void Run(const Case& c, int repeats) {
  std::map<std::string, std::vector<double>> stages;
  std::vector<std::string> order;
  std::vector<double> totals, no_decode, cpu;
  size_t vertices = 0;
  for (int i = 0; i < repeats + 1; ++i) {
    const double c0 = CpuMs();
    auto r = rheo::sketch::ContourFromSketchBytes(c.bytes, ContourOptions{});
    const double c1 = CpuMs();
    if (!r.ok()) {
      std::printf("%s: error %s\n", c.name.c_str(), r.error().message.c_str());
      return;
    }
    if (i == 0) continue;  // warm-up
    double total = 0, decode = 0;
    for (const auto& t : r->timings) {
      if (!stages.count(t.stage)) order.push_back(t.stage);
      stages[t.stage].push_back(t.ms);
      total += t.ms;
      if (t.stage == "decode" || t.stage == "parse") decode += t.ms;
    }
    totals.push_back(total);
    cpu.push_back(c1 - c0);
    no_decode.push_back(total - decode);
    vertices = r->contour.points.size();
  }
  std::printf("\n%s  (%zu vertices, median of %d runs)\n", c.name.c_str(), vertices, repeats);
  for (const auto& s : order) std::printf("  %-24s %9.3f ms\n", s.c_str(), Median(stages[s]));
  const double t = Median(totals);
  std::printf("  %-24s %9.3f ms\n", "total", t);
  std::printf("  %-24s %9.3f ms\n", "total without decode", Median(no_decode));
  std::printf("  %-24s %9.3f ms\n", "total, CPU time", Median(cpu));
  if (c.target_ms > 0) {
    std::printf("  %-24s %9.3f ms   ratio wall/target %.2f, CPU/target %.2f\n", "target",
                c.target_ms, t / c.target_ms, Median(cpu) / c.target_ms);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const int repeats = argc > 1 ? std::max(1, std::atoi(argv[1])) : 21;
  namespace t = rheo::sketch::testing;
  std::vector<Case> cases;
  for (int size : {512, 2048}) {
    const double s = size / 512.0;
    t::Picture p = t::Blank(size, size);
    auto star = t::Star({256 * s, 256 * s}, 200 * s, 120 * s, 5, 1500 * int(s));
    t::InkPolyline(p, star, true, 4.0 * s);
    cases.push_back({"picture " + std::to_string(size) + " x " + std::to_string(size) +
                         " PNG, star, line " + std::to_string(int(4 * s)) + " px",
                     t::EncodePng(p), size == 2048 ? 40.0 : 0.0});
    if (size == 2048) {
      std::mt19937 rng(1);
      t::Picture q = t::Blank(size, size, 230);
      t::InkPolyline(q, star, true, 4.0 * s, 50);
      t::UnevenLight(q, 0.3, 3.0, rng);
      cases.push_back(
          {"photo 2048 x 2048 JPEG q80, uneven light (adaptive)", t::EncodeJpeg(q, 80), 40.0});
    }
  }
  // 2,000 points in 3 overlapping noisy strokes.
  std::mt19937 rng(2);
  std::normal_distribution<double> n(0.0, 0.5);
  auto curve = t::Star({256, 256}, 200, 120, 5, 2000);
  std::vector<std::vector<Vec2>> strokes(3);
  for (int k = 0; k < 3; ++k) {
    for (int i = k * 2000 / 3; i < (k + 1) * 2000 / 3 + 12; ++i) {
      strokes[k].push_back(curve[i % 2000] + Vec2(n(rng), n(rng)));
    }
  }
  const std::string json = t::StrokesJson(512, 512, strokes);
  cases.push_back({"strokes: 2,036 points in 3 overlapping strokes",
                   std::vector<uint8_t>(json.begin(), json.end()), 1.0});
  for (const auto& c : cases) Run(c, repeats);
  return 0;
}
