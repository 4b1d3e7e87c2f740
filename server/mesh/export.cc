// Surface and triangulation exports as strings.
#include <cstdio>
#include <sstream>

#include "mesh/mesh.h"

namespace rheo::mesh {
namespace {

Vec3 Normal(const TetMesh& m, const std::array<int32_t, 3>& f) {
  const Vec3 n =
      (m.positions[f[1]] - m.positions[f[0]]).cross(m.positions[f[2]] - m.positions[f[0]]);
  const double len = n.norm();
  return len > 0 ? Vec3(n / len) : Vec3(0, 0, 0);
}

}  // namespace

std::string SurfaceToObj(const TetMesh& mesh) {
  std::ostringstream os;
  os.precision(17);
  os << "# rheo mesh surface [m]\n";
  for (const Vec3& p : mesh.positions) os << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  for (const auto& f : mesh.surface)
    os << "f " << f[0] + 1 << ' ' << f[1] + 1 << ' ' << f[2] + 1 << '\n';
  return os.str();
}

std::string SurfaceToPly(const TetMesh& mesh) {
  std::ostringstream os;
  os.precision(17);
  os << "ply\nformat ascii 1.0\ncomment rheo mesh surface [m]\nelement vertex "
     << mesh.positions.size() << "\nproperty double x\nproperty double y\nproperty double z\n"
     << "element face " << mesh.surface.size() << "\nproperty list uchar int vertex_indices\n"
     << "end_header\n";
  for (const Vec3& p : mesh.positions) os << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  for (const auto& f : mesh.surface) os << "3 " << f[0] << ' ' << f[1] << ' ' << f[2] << '\n';
  return os.str();
}

std::string SurfaceToStl(const TetMesh& mesh) {
  std::ostringstream os;
  os.precision(17);
  os << "solid rheo\n";
  for (const auto& f : mesh.surface) {
    const Vec3 n = Normal(mesh, f);
    os << "  facet normal " << n.x() << ' ' << n.y() << ' ' << n.z() << "\n    outer loop\n";
    for (int i = 0; i < 3; ++i) {
      const Vec3& p = mesh.positions[f[i]];
      os << "      vertex " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    }
    os << "    endloop\n  endfacet\n";
  }
  os << "endsolid rheo\n";
  return os.str();
}

std::string TriangulationToSvg(const MeshResult& r) {
  const auto& pts = r.cdt.points;
  Vec2 lo(0, 0), hi(1, 1);
  if (!pts.empty()) {
    lo = hi = pts[0];
    for (const Vec2& p : pts) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  }
  const double ext = std::max(hi.x() - lo.x(), hi.y() - lo.y());
  const double scale = ext > 0 ? 800.0 / ext : 1.0;  // [px/m] in the picture
  auto X = [&](const Vec2& p) { return 10 + (p.x() - lo.x()) * scale; };
  auto Y = [&](const Vec2& p) { return 10 + (hi.y() - p.y()) * scale; };  // y up -> down
  const double w = (hi.x() - lo.x()) * scale + 20, h = (hi.y() - lo.y()) * scale + 20;
  std::ostringstream os;
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
                "viewBox=\"0 0 %.2f %.2f\">\n",
                w, h, w, h);
  os << buf
     << "<title>CDT by triangle class: terminal (red), sleeve (yellow), junction (blue); "
        "Teddy final triangulation (grey) and spine (black)</title>\n";
  const char* fill[4] = {"#6fa8dc", "#ffd966", "#e06666", "#b4a7d6"};
  os << "<g stroke=\"#333\" stroke-width=\"0.6\">\n";
  for (size_t t = 0; t < r.cdt.triangles.size(); ++t) {
    const auto& tr = r.cdt.triangles[t];
    const int c = static_cast<int>(r.cdt.classes[t]);
    std::snprintf(buf, sizeof buf,
                  "<polygon class=\"%s\" fill=\"%s\" points=\"%.2f,%.2f %.2f,%.2f %.2f,%.2f\"/>\n",
                  TriangleClassName(r.cdt.classes[t]), fill[c], X(pts[tr[0]]), Y(pts[tr[0]]),
                  X(pts[tr[1]]), Y(pts[tr[1]]), X(pts[tr[2]]), Y(pts[tr[2]]));
    os << buf;
  }
  os << "</g>\n<g stroke=\"#777\" stroke-width=\"0.4\" fill=\"none\">\n";
  const auto& tp = r.teddy.points;
  for (const auto& tr : r.teddy.triangles) {
    std::snprintf(buf, sizeof buf, "<polygon points=\"%.2f,%.2f %.2f,%.2f %.2f,%.2f\"/>\n",
                  X(tp[tr[0]]), Y(tp[tr[0]]), X(tp[tr[1]]), Y(tp[tr[1]]), X(tp[tr[2]]),
                  Y(tp[tr[2]]));
    os << buf;
  }
  os << "</g>\n<g stroke=\"#000\" stroke-width=\"1.5\">\n";
  for (const auto& e : r.teddy.spine_edges) {
    std::snprintf(buf, sizeof buf, "<line x1=\"%.2f\" y1=\"%.2f\" x2=\"%.2f\" y2=\"%.2f\"/>\n",
                  X(tp[e[0]]), Y(tp[e[0]]), X(tp[e[1]]), Y(tp[e[1]]));
    os << buf;
  }
  os << "</g>\n</svg>\n";
  return os.str();
}

}  // namespace rheo::mesh
