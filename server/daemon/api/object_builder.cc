#include "daemon/api/object_builder.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "daemon/api/convert.h"
#include "mesh/mesh.h"
#include "sketch/sketch.h"

namespace rheo::daemon {
namespace {

Result<sketch::ContourResult> RunSketch(const v1::Sketch& s, const v1::ContourOptions& o,
                                        const CancelToken& cancel) {
  sketch::ContourOptions opts = ToSketchOptions(o);
  opts.cancel = cancel;
  switch (s.source_case()) {
    case v1::Sketch::kStrokesJson: return sketch::ContourFromStrokesJson(s.strokes_json(), opts);
    case v1::Sketch::kImage: {
      const auto& b = s.image();
      return sketch::ContourFromImage(
          std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(b.data()), b.size()), opts);
    }
    case v1::Sketch::kContour: {
      sketch::ContourResult r;
      for (const auto& p : s.contour().points()) r.contour.points.emplace_back(p.x(), p.y());
      if (r.contour.points.size() < 3)
        return InvalidArgument("sketch.contour needs at least 3 points, got " +
                               std::to_string(r.contour.points.size()));
      for (const Vec2& p : r.contour.points)
        if (!std::isfinite(p.x()) || !std::isfinite(p.y()))
          return InvalidArgument("sketch.contour has a non-finite coordinate");
      return r;
    }
    case v1::Sketch::SOURCE_NOT_SET: break;
  }
  return InvalidArgument("sketch is empty: set strokes_json, image or contour");
}

const char* SketchKind(const v1::Sketch& s) {
  switch (s.source_case()) {
    case v1::Sketch::kStrokesJson: return "strokes";
    case v1::Sketch::kImage: return "image";
    case v1::Sketch::kContour: return "contour";
    default: return "none";
  }
}

// %g: small and large values keep their digits (1e-09, not 0.000000).
std::string Num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

Status CheckRange(const char* field, double v, double lo, double hi, const char* unit) {
  if (v == 0) return Status::Ok();  // 0 = default
  if (!(v >= lo && v <= hi))
    return InvalidArgument(std::string(field) + " must be 0 (default) or between " + Num(lo) +
                           " and " + Num(hi) + (*unit ? " " : "") + unit + "; got " + Num(v));
  return Status::Ok();
}

}  // namespace

Status ValidateCreateRequest(const v1::CreateObjectRequest& r) {
  if (r.sketch().source_case() == v1::Sketch::SOURCE_NOT_SET)
    return InvalidArgument("sketch is empty: set strokes_json, image or contour");
  if (r.name().size() > 200) return InvalidArgument("name is longer than 200 characters");
  constexpr size_t kMaxBytes = 32u << 20;
  if (r.sketch().image().size() > kMaxBytes || r.sketch().strokes_json().size() > kMaxBytes)
    return ResourceExhausted("sketch is larger than the 32 MB limit");
  if (r.sketch().background_image().size() > kMaxBytes)
    return ResourceExhausted("background_image is larger than the 32 MB limit");
  if (r.sketch().contour().points_size() > 100000)
    return ResourceExhausted("sketch.contour has more than the 100000-point limit");
  for (Status s :
       {CheckRange("contour_options.epsilon_px", r.contour_options().epsilon_px(), 0.1, 50, "px"),
        CheckRange("contour_options.max_gap_fraction", r.contour_options().max_gap_fraction(), 1e-4,
                   0.5, ""),
        CheckRange("mesh_options.thickness", r.mesh_options().thickness(), 0.05, 10, ""),
        CheckRange("mesh_options.resolution", r.mesh_options().resolution(), 5e-4, 0.5, "m"),
        CheckRange("mesh_options.pixel_size", r.mesh_options().pixel_size(), 1e-6, 1e-2, "m/px")})
    if (!s.ok()) return s;
  if (!v1::Division_IsValid(r.mesh_options().division()))
    return InvalidArgument(
        "mesh_options.division must be DIVISION_QUALITY (0) or DIVISION_PAPER "
        "(1), got " +
        std::to_string(r.mesh_options().division()));
  return Status::Ok();
}

Result<v1::ContourReport> ExtractContour(const v1::Sketch& sketch,
                                         const v1::ContourOptions& options,
                                         const CancelToken& cancel) {
  auto r = RunSketch(sketch, options, cancel);
  if (!r.ok()) return r.error();
  v1::ContourReport out;
  FillContourReport(*r, &out);
  return out;
}

Status CheckBackgroundImage(const std::string& bytes) {
  if (bytes.empty()) return Status::Ok();
  // Decoded in full, with a sketch picture's limits: what sketch pads will show must be a
  // picture they can open, not any bytes.
  auto size = sketch::DecodePictureSize(
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()),
      sketch::ContourOptions{});
  if (!size.ok())
    return Error{size.error().code, "background_image (" + std::to_string(bytes.size()) +
                                        " bytes): " + size.error().message +
                                        "; upload the photo as PNG or JPEG"};
  return Status::Ok();
}

Result<StoredObject> BuildObject(const v1::CreateObjectRequest& request, const BuildLimits& limits,
                                 const BuildProgress& progress, const CancelToken& cancel) {
  v1::CreateObjectProgress p;
  p.set_stage("contour");
  p.set_fraction(0.0);
  if (auto stop = progress(p)) return *stop;
  if (Status s = CheckBackgroundImage(request.sketch().background_image()); !s.ok())
    return s.error();

  auto contour = RunSketch(request.sketch(), request.contour_options(), cancel);
  if (!contour.ok()) return contour.error();
  v1::Object object;
  FillContourReport(*contour, object.mutable_contour());
  p.set_fraction(0.1);
  *p.mutable_contour() = object.contour();
  if (auto stop = progress(p)) return *stop;
  p.clear_contour();

  mesh::MeshOptions mo;
  const auto& rm = request.mesh_options();
  if (rm.thickness() > 0) mo.thickness = rm.thickness();
  if (rm.resolution() > 0) mo.resolution = rm.resolution();
  mo.division =
      rm.division() == v1::DIVISION_PAPER ? mesh::Division::kPaper : mesh::Division::kQuality;
  if (rm.pixel_size() > 0) mo.pixel_size = rm.pixel_size();
  mo.max_tets = limits.max_tets;
  mo.max_vertices = limits.max_vertices;
  mo.cancel = cancel;
  std::optional<Error> stopped;
  mo.progress = [&](std::string_view stage, double fraction) {
    p.set_stage(std::string(stage));
    p.set_fraction(0.1 + 0.85 * fraction);
    stopped = progress(p);
    return !stopped.has_value();
  };
  auto built = mesh::BuildSolid(contour->contour, mo);
  if (stopped) return *stopped;
  if (!built.ok()) return built.error();
  if (!built->quality.valid) {
    std::string why;
    for (const auto& f : built->quality.failures) why += (why.empty() ? "" : "; ") + f;
    return Internal("the mesh failed its validity checks: " + why);
  }
  FillMeshReport(*built, object.mutable_mesh());

  StoredObject out;
  out.id = Store::NewId();
  out.name = request.name().empty() ? out.id : request.name();
  out.created_unix_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
  Eigen::AlignedBox3d box;
  for (const Vec3& x : built->mesh.positions) box.extend(x);
  const Vec3 lo = box.min(), hi = box.max();
  object.set_id(out.id);
  object.set_name(out.name);
  object.mutable_created()->set_seconds(out.created_unix_ms / 1000);
  object.mutable_created()->set_nanos(static_cast<int32_t>(out.created_unix_ms % 1000) * 1000000);
  *object.mutable_contour_options() = request.contour_options();
  *object.mutable_mesh_options() = request.mesh_options();
  object.mutable_bounds_min()->set_x(lo.x());
  object.mutable_bounds_min()->set_y(lo.y());
  object.mutable_bounds_min()->set_z(lo.z());
  object.mutable_bounds_max()->set_x(hi.x());
  object.mutable_bounds_max()->set_y(hi.y());
  object.mutable_bounds_max()->set_z(hi.z());
  object.set_has_background_image(!request.sketch().background_image().empty());
  out.meta = object.SerializeAsString();
  out.sketch_kind = SketchKind(request.sketch());
  switch (request.sketch().source_case()) {
    case v1::Sketch::kStrokesJson: out.sketch = request.sketch().strokes_json(); break;
    case v1::Sketch::kImage: out.sketch = request.sketch().image(); break;
    default: out.sketch = request.sketch().contour().SerializeAsString(); break;
  }
  out.background = request.sketch().background_image();
  out.triangulation_svg = mesh::TriangulationToSvg(*built);
  out.mesh = std::move(built->mesh);
  return out;
}

}  // namespace rheo::daemon
