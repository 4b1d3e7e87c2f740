// BuildSolid: the pipeline, with limits, progress, cancellation and stage timings.
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "mesh/internal.h"

namespace rheo::mesh {
namespace {

class Stages {
 public:
  Stages(const ProgressFn& progress, const CancelToken& cancel, std::vector<StageTiming>& timings)
      : progress_(progress), cancel_(cancel), timings_(timings) {}
  // Closes the running stage and asks the hook whether to go on into `next`.
  bool Next(std::string_view finished, std::string_view next, double fraction) {
    const auto now = std::chrono::steady_clock::now();
    if (!finished.empty())
      timings_.push_back({std::string(finished), std::chrono::duration<double>(now - t0_).count()});
    t0_ = now;
    if (cancel_.stop_requested()) return false;
    return !progress_ || progress_(next, fraction);
  }
  // Why Next returned false (or the token stopped a stage's loop): the token's reason, else the
  // progress hook's cancel.
  Error Stopped(std::string_view stage) const {
    if (Status s = cancel_.Check("the mesh stage '" + std::string(stage) + "'"); !s)
      return s.error();
    return Cancelled("mesh build cancelled before stage '" + std::string(stage) + "'");
  }

 private:
  const ProgressFn& progress_;
  const CancelToken& cancel_;
  std::vector<StageTiming>& timings_;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

// %g: small and large values keep their digits (2.1e-12, not 0.000000).
std::string Num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
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
  Stages st(options.progress, options.cancel, r.timings);
  if (!st.Next("", "contour", 0.0)) return st.Stopped("contour");
  auto metres = internal::ContourToMetres(contour_px, options.pixel_size);
  if (!metres.ok()) return metres.error();
  {
    Eigen::AlignedBox2d box;
    for (const Vec2& q : *metres) box.extend(q);
    const Vec2 size = box.sizes();
    if (!(std::min(size.x(), size.y()) >= options.min_object_size)) {
      return InvalidArgument("the solid is " + Num(size.x()) + " m x " + Num(size.y()) +
                             " m across; objects must be at least " + Num(options.min_object_size) +
                             " m (" + Num(options.min_object_size * 1e3) +
                             " mm) across both ways (min_object_size): draw larger or raise "
                             "pixel_size (now " +
                             Num(options.pixel_size) + " m/px)");
    }
  }
  auto resampled =
      internal::ResampleContour(*metres, options.resolution, options.pixel_size, options.cancel);
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

  if (!st.Next("contour", "cdt", 0.1)) return st.Stopped("cdt");
  auto cdt = internal::TriangulateWithNeighbors(r.contour);
  if (!cdt.ok()) return cdt.error();

  // The CGAL calls (this triangulation, the 2D mesher) cannot be interrupted; their input is
  // bounded instead: max_contour_points above, and the 2D mesh estimate against max_vertices.
  if (!st.Next("cdt", "teddy", 0.2)) return st.Stopped("teddy");
  auto teddy = internal::BuildTeddy(*cdt, options.thickness);
  if (!teddy.ok()) return teddy.error();
  r.cdt = std::move(cdt->tri);
  r.teddy = std::move(*teddy);

  if (!st.Next("teddy", "mesh2d", 0.3)) return st.Stopped("mesh2d");
  auto mesh2 = options.division == Division::kPaper
                   ? internal::PaperMesh(r.teddy, options.resolution)
                   : internal::QualityMesh(r.contour, options.resolution);
  if (!mesh2.ok()) return mesh2.error();

  if (!st.Next("mesh2d", "inflate", 0.5)) return st.Stopped("inflate");
  internal::HeightField height(r.teddy);
  std::vector<double> z(mesh2->tri.points.size(), 0.0);
  for (size_t v = 0; v < z.size(); ++v) {
    if ((v & 4095) == 4095 && options.cancel.stop_requested()) return st.Stopped("inflate");
    if (!mesh2->on_contour[v]) z[v] = height(mesh2->tri.points[v]);
  }

  if (!st.Next("inflate", "tetrahedra", 0.6)) return st.Stopped("tetrahedra");
  auto tets = internal::BuildColumns(*mesh2, z, options.resolution,
                                     {options.max_vertices, options.max_tets});
  if (!tets.ok()) return tets.error();
  r.mesh = std::move(*tets);
  internal::ImproveTets(
      r.mesh, 15.0, 8, [&height](const Vec2& p) { return height(p); }, options.cancel);
  if (options.cancel.stop_requested()) return st.Stopped("tetrahedra");
  {
    double smallest = INFINITY;
    const auto& P = r.mesh.positions;
    for (const auto& t : r.mesh.tets)
      smallest = std::min(
          smallest,
          std::abs((P[t[1]] - P[t[0]]).dot((P[t[2]] - P[t[0]]).cross(P[t[3]] - P[t[0]]))) / 6.0);
    if (!r.mesh.tets.empty() && !(smallest >= options.min_tet_volume)) {
      return InvalidArgument("the mesh has a tetrahedron of " + Num(smallest) +
                             " m^3; tetrahedra must be at least " + Num(options.min_tet_volume) +
                             " m^3 (min_tet_volume): draw larger or lower the resolution (now " +
                             Num(options.resolution) + " m)");
    }
  }
  r.mesh2d = std::move(mesh2->tri);

  if (!st.Next("tetrahedra", "quality", 0.8)) return st.Stopped("quality");
  r.quality = CheckTetMesh(r.mesh);
  st.Next("quality", "done", 1.0);
  return r;
}

}  // namespace rheo::mesh
