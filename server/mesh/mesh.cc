// BuildSolid: the pipeline, with limits, progress, cancellation and stage timings.
#include <chrono>
#include <cmath>
#include <cstdio>

#include "mesh/internal.h"

namespace rheo::mesh {
namespace {

class Stages {
 public:
  Stages(const ProgressFn& progress, std::vector<StageTiming>& timings)
      : progress_(progress), timings_(timings) {}
  // Closes the running stage and asks the hook whether to go on into `next`.
  bool Next(std::string_view finished, std::string_view next, double fraction) {
    const auto now = std::chrono::steady_clock::now();
    if (!finished.empty())
      timings_.push_back({std::string(finished), std::chrono::duration<double>(now - t0_).count()});
    t0_ = now;
    return !progress_ || progress_(next, fraction);
  }

 private:
  const ProgressFn& progress_;
  std::vector<StageTiming>& timings_;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

Error CancelledIn(std::string_view stage) {
  return Cancelled("mesh build cancelled before stage '" + std::string(stage) + "'");
}

}  // namespace

Result<MeshResult> BuildSolid(const Polygon2& contour_px, const MeshOptions& options) {
  if (!(options.resolution > 0) || !std::isfinite(options.resolution))
    return InvalidArgument("resolution must be a positive edge length in metres");
  if (!(options.thickness > 0) || !std::isfinite(options.thickness))
    return InvalidArgument("thickness must be a positive scale factor");
  if (static_cast<int64_t>(contour_px.points.size()) > options.max_contour_points)
    return ResourceExhausted("contour has " + std::to_string(contour_px.points.size()) +
                             " points, over the limit max_contour_points = " +
                             std::to_string(options.max_contour_points));
  MeshResult r;
  Stages st(options.progress, r.timings);
  if (!st.Next("", "contour", 0.0)) return CancelledIn("contour");
  auto metres = internal::ContourToMetres(contour_px, options.pixel_size);
  if (!metres.ok()) return metres.error();
  auto resampled = internal::ResampleContour(*metres, options.resolution, options.pixel_size);
  if (!resampled.ok()) return resampled.error();
  r.contour = std::move(*resampled);

  // A coarse estimate first, so a huge request fails before the triangulation and the 2D mesher
  // run.
  double area = 0;
  for (size_t i = 0, n = r.contour.size(); i < n; ++i)
    area += r.contour[i].x() * r.contour[(i + 1) % n].y() -
            r.contour[(i + 1) % n].x() * r.contour[i].y();
  const double tri_estimate =
      0.5 * std::abs(area) / (0.35 * options.resolution * options.resolution);
  if (!std::isfinite(tri_estimate))
    return InvalidArgument(
        "the contour is too large to mesh: its area does not fit a double (coordinates of "
        "about 1e150 m or more after pixel_size); scale the sketch down");
  if (tri_estimate > 2.0 * static_cast<double>(options.max_vertices)) {
    char about[32];
    std::snprintf(about, sizeof about, tri_estimate < 2e15 ? "%.0f" : "%.3g", tri_estimate / 2);
    return ResourceExhausted("the 2D mesh alone would need about " + std::string(about) +
                             " vertices, over the limit max_vertices = " +
                             std::to_string(options.max_vertices) + "; raise the resolution");
  }

  if (!st.Next("contour", "cdt", 0.1)) return CancelledIn("cdt");
  auto cdt = internal::TriangulateWithNeighbors(r.contour);
  if (!cdt.ok()) return cdt.error();

  if (!st.Next("cdt", "teddy", 0.2)) return CancelledIn("teddy");
  auto teddy = internal::BuildTeddy(*cdt, options.thickness);
  if (!teddy.ok()) return teddy.error();
  r.cdt = std::move(cdt->tri);
  r.teddy = std::move(*teddy);

  if (!st.Next("teddy", "mesh2d", 0.3)) return CancelledIn("mesh2d");
  auto mesh2 = options.division == Division::kPaper
                   ? internal::PaperMesh(r.teddy, options.resolution)
                   : internal::QualityMesh(r.contour, options.resolution);
  if (!mesh2.ok()) return mesh2.error();

  if (!st.Next("mesh2d", "inflate", 0.5)) return CancelledIn("inflate");
  internal::HeightField height(r.teddy);
  std::vector<double> z(mesh2->tri.points.size(), 0.0);
  for (size_t v = 0; v < z.size(); ++v)
    if (!mesh2->on_contour[v]) z[v] = height(mesh2->tri.points[v]);

  if (!st.Next("inflate", "tetrahedra", 0.6)) return CancelledIn("tetrahedra");
  auto tets = internal::BuildColumns(*mesh2, z, options.resolution,
                                     {options.max_vertices, options.max_tets});
  if (!tets.ok()) return tets.error();
  r.mesh = std::move(*tets);
  internal::ImproveTets(r.mesh, 15.0, 8, [&height](const Vec2& p) { return height(p); });
  r.mesh2d = std::move(mesh2->tri);

  if (!st.Next("tetrahedra", "quality", 0.8)) return CancelledIn("quality");
  r.quality = CheckTetMesh(r.mesh);
  st.Next("quality", "done", 1.0);
  return r;
}

}  // namespace rheo::mesh
