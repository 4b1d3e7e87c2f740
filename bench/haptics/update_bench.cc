// Time per Renderer::Update on spheres of about 2k, 10k and 50k triangles while the tool presses
// and slides over a small region of a slowly breathing surface. Prints medians, p99 and ratios to
// the smallest surface, for the default round-robin re-binning and for a full re-bin every tick.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <vector>

#include "haptics/haptics.h"

namespace {

using rheo::Vec3;
using rheo::haptics::Renderer;
using rheo::haptics::RendererConfig;

struct Surface {
  std::vector<Vec3> x;
  std::vector<std::array<int32_t, 3>> tris;
};

// Latitude-longitude sphere, 2 lon (lat - 1) triangles.
Surface Sphere(double radius, int lat, int lon) {
  Surface s;
  const double pi = std::numbers::pi;
  s.x.push_back(Vec3(0, 0, radius));
  for (int i = 1; i < lat; ++i)
    for (int j = 0; j < lon; ++j) {
      const double th = pi * i / lat, ph = 2 * pi * j / lon;
      s.x.push_back(radius *
                    Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
    }
  s.x.push_back(Vec3(0, 0, -radius));
  const int32_t south = static_cast<int32_t>(s.x.size()) - 1;
  auto ring = [&](int i, int j) { return 1 + (i - 1) * lon + (j % lon); };
  for (int j = 0; j < lon; ++j) s.tris.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i < lat - 1; ++i)
    for (int j = 0; j < lon; ++j) {
      s.tris.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      s.tris.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  for (int j = 0; j < lon; ++j) s.tris.push_back({south, ring(lat - 1, j + 1), ring(lat - 1, j)});
  return s;
}

struct Stats {
  double median_us, p99_us, candidates, contact_fraction;
};

Stats Run(const Surface& s, double kRadius, int32_t rebin) {
  constexpr double kDt = 1e-3;
  constexpr int kWarm = 500, kTicks = 5000;
  RendererConfig c;
  c.tool_radius = 0.003;
  c.static_friction = 0.3;
  c.dynamic_friction = 0.2;
  c.rebin_faces_per_tick = rebin;
  c.max_surface_speed = 0.05;  // breathing below: 0.2 mm at 2 Hz, well under 5 cm/s
  std::vector<Vec3> x = s.x;
  const double pi = std::numbers::pi;
  auto device_at = [&](int i) {
    const double t = i * kDt;
    const Vec3 centre(kRadius + c.tool_radius - 0.002, 0.0, 0.0);
    return Vec3(centre + 0.005 * Vec3(0.0, std::cos(2 * pi * t), std::sin(2 * pi * t)));
  };
  const Vec3 start(kRadius + 0.03, 0.0, 0.0);
  auto made = Renderer::Create(c, s.tris, x, start);
  if (!made.ok()) {
    std::fprintf(stderr, "%s\n", made.error().message.c_str());
    std::exit(2);
  }
  Renderer r = std::move(made).value();
  std::vector<double> us;
  us.reserve(kTicks);
  double candidates = 0;
  int contact = 0;
  Vec3 device = start;
  for (int i = 1; i <= kWarm + kTicks; ++i) {
    const double scale = 1.0 + 0.004 * std::sin(2 * pi * 2.0 * i * kDt);
    for (size_t n = 0; n < x.size(); ++n) x[n] = scale * s.x[n];
    // Approach for the first 400 ticks, then circle on the surface.
    const Vec3 goal = device_at(i);
    device = i < 400 ? Vec3(device + (goal - device) / (400.0 - i)) : goal;
    const auto t0 = std::chrono::steady_clock::now();
    auto out = r.Update({device, Vec3::Zero()}, x, kDt);
    const auto t1 = std::chrono::steady_clock::now();
    if (!out.ok()) std::exit(2);
    if (i > kWarm) {
      us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
      candidates += out->candidate_faces;
      contact += out->in_contact;
    }
  }
  std::sort(us.begin(), us.end());
  return {us[us.size() / 2], us[us.size() * 99 / 100], candidates / kTicks,
          static_cast<double>(contact) / kTicks};
}

void Table(const char* title, double radius0, bool grow) {
  struct Size {
    int lat, lon;
  };
  const Size sizes[] = {{23, 46}, {51, 100}, {113, 222}};
  std::printf("\n%s\n", title);
  std::printf("%9s %6s | %-28s | %-28s | %-21s\n", "", "", "re-bin 256 faces/tick",
              "re-bin 1024 faces/tick", "re-bin all faces/tick");
  std::printf("%9s %6s |", "triangles", "R[cm]");
  for (int k = 0; k < 2; ++k)
    std::printf(" %7s %7s %5s %6s |", "med[us]", "p99[us]", "ratio", "faces");
  std::printf(" %7s %7s %5s\n", "med[us]", "p99[us]", "ratio");
  double base[3] = {0, 0, 0};
  for (const Size& z : sizes) {
    const double m0 = 2.0 * 46 * 22;
    const double radius = grow ? radius0 * std::sqrt(2.0 * z.lon * (z.lat - 1) / m0) : radius0;
    const Surface s = Sphere(radius, z.lat, z.lon);
    const int32_t m = static_cast<int32_t>(s.tris.size());
    const int32_t budgets[3] = {256, 1024, m};
    std::printf("%9d %6.1f |", m, 100 * radius);
    double contact = 0;
    for (int k = 0; k < 3; ++k) {
      const Stats st = Run(s, radius, budgets[k]);
      if (base[k] == 0) base[k] = st.median_us;
      if (k < 2) {
        std::printf(" %7.2f %7.2f %5.2f %6.0f |", st.median_us, st.p99_us, st.median_us / base[k],
                    st.candidates);
      } else {
        std::printf(" %7.2f %7.2f %5.2f", st.median_us, st.p99_us, st.median_us / base[k]);
      }
      contact = st.contact_fraction;
    }
    std::printf("  (in contact %.0f%%)\n", 100 * contact);
  }
}

}  // namespace

int main() {
  std::printf(
      "Renderer::Update: tool r = 3 mm pressing 2 mm into a breathing sphere and circling\n"
      "5 mm at 1 Hz with friction; 5000 ticks after 500 warm-up; 'faces' = faces the\n"
      "local search examined per tick (mean); ratio = median / median of the first row;\n"
      "surface speed bound 5 cm/s (the search margin grows with it x sweep length).\n");
  Table("A. Same triangle size (about 4.5 mm edges), surface grows with the triangle count", 0.03,
        true);
  Table("B. Same 5 cm sphere, finer triangles (more faces under the tool)", 0.05, false);
  return 0;
}
