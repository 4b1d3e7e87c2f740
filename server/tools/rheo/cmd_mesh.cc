// `rheo mesh INPUT --out FILE.vtu`: sketch or contour JSON -> Teddy solid -> tetrahedra, with a
// report.
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <span>
#include <sstream>

#include "commands.h"
#include "common/tet_mesh_io.h"
#include "mesh/mesh.h"
#ifdef RHEO_HAVE_SKETCH
#include "sketch/sketch.h"
#endif

namespace rheo::tools {
namespace {

struct MeshArgs {
  std::string input;
  std::string out;
  std::string surface;
  std::string svg;
  double thickness = 1.0;
  double resolution = 0;
  double pixel_size = 0;
  std::string division = "quality";
  bool json = false;
};

bool WriteFile(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  return static_cast<bool>(f);
}

int RunMesh(const MeshArgs& a) {
  std::ifstream in(a.input, std::ios::binary);
  if (!in) {
    std::cerr << "rheo mesh: cannot open " << a.input << "\n";
    return 1;
  }
  std::stringstream buf;
  buf << in.rdbuf();
  const std::string bytes = buf.str();
  Polygon2 contour;
  nlohmann::json j = nlohmann::json::parse(bytes, nullptr, /*allow_exceptions=*/false);
  if (!j.is_discarded() && j.is_object() && j.contains("contour")) {
    if (!j["contour"].is_array()) {
      std::cerr << "rheo mesh: " << a.input << ": \"contour\" is not an array of [x, y] points\n";
      return 1;
    }
    for (const auto& p : j["contour"]) {
      if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) {
        std::cerr << "rheo mesh: contour point " << contour.points.size()
                  << " is not an [x, y] pair\n";
        return 1;
      }
      contour.points.emplace_back(p[0].get<double>(), p[1].get<double>());
    }
  } else {
#ifdef RHEO_HAVE_SKETCH
    // A sketch (stroke JSON, PNG or JPEG): the sketch stage makes the contour first.
    auto c = sketch::ContourFromSketchBytes(
        std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()),
        sketch::ContourOptions{});
    if (!c.ok()) {
      std::cerr << "rheo mesh: " << a.input << ": " << c.error().message << "\n";
      return 1;
    }
    contour = c->contour;
#else
    std::cerr << "rheo mesh: " << a.input << " has no \"contour\" array of [x, y] points\n";
    return 1;
#endif
  }
  mesh::MeshOptions opt;
  opt.thickness = a.thickness;
  if (a.resolution > 0) opt.resolution = a.resolution;
  if (a.pixel_size > 0) opt.pixel_size = a.pixel_size;
  opt.division = a.division == "paper" ? mesh::Division::kPaper : mesh::Division::kQuality;
  auto r = mesh::BuildSolid(contour, opt);
  if (!r.ok()) {
    std::cerr << "rheo mesh: " << ErrorCodeName(r.error().code) << ": " << r.error().message
              << "\n";
    return r.error().code == ErrorCode::kInternal ? 2 : 1;
  }
  if (!WriteFile(a.out, WriteVtu(r->mesh))) {
    std::cerr << "rheo mesh: cannot write " << a.out << "\n";
    return 2;
  }
  if (!a.surface.empty()) {
    const std::string ext = a.surface.substr(a.surface.find_last_of('.') + 1);
    const std::string text = ext == "ply"   ? mesh::SurfaceToPly(r->mesh)
                             : ext == "stl" ? mesh::SurfaceToStl(r->mesh)
                                            : mesh::SurfaceToObj(r->mesh);
    if (!WriteFile(a.surface, text)) {
      std::cerr << "rheo mesh: cannot write " << a.surface << "\n";
      return 2;
    }
  }
  if (!a.svg.empty() && !WriteFile(a.svg, mesh::TriangulationToSvg(*r))) {
    std::cerr << "rheo mesh: cannot write " << a.svg << "\n";
    return 2;
  }
  const auto& q = r->quality;
  if (a.json) {
    nlohmann::json j;
    j["input"] = a.input;
    j["options"] = {{"pixel_size_m", opt.pixel_size},
                    {"thickness", opt.thickness},
                    {"resolution_m", opt.resolution},
                    {"division", a.division}};
    j["counts"] = {{"contour_points_in", contour.points.size()},
                   {"contour_points_meshed", r->contour.size()},
                   {"cdt_triangles", r->cdt.triangles.size()},
                   {"teddy_triangles", r->teddy.triangles.size()},
                   {"spine_edges", r->teddy.spine_edges.size()},
                   {"pruned_branches", r->teddy.pruned_branches},
                   {"mesh2d_triangles", r->mesh2d.triangles.size()},
                   {"vertices", q.num_vertices},
                   {"tets", q.num_tets},
                   {"surface_faces", q.num_surface_faces}};
    int cls[4] = {0, 0, 0, 0};
    for (auto c : r->cdt.classes) ++cls[static_cast<int>(c)];
    j["cdt_classes"] = {{"terminal", cls[2]}, {"sleeve", cls[1]}, {"junction", cls[0]}};
    int types[4] = {0, 0, 0, 0};
    for (auto c : r->teddy.spine_count) ++types[std::min<int>(c, 3)];
    j["teddy_triangle_types"] = {{"one_spine_point", types[1]},
                                 {"two_spine_points", types[2]},
                                 {"three_spine_points", types[3]}};
    j["quality"] = {{"valid", q.valid},
                    {"failures", q.failures},
                    {"nonpositive_tets", q.num_nonpositive_tets},
                    {"boundary_matches_surface", q.boundary_matches_surface},
                    {"surface_closed", q.surface_closed},
                    {"surface_manifold", q.surface_manifold},
                    {"surface_outward", q.surface_outward},
                    {"tet_volume_sum_m3", q.tet_volume_sum},
                    {"surface_volume_m3", q.surface_volume},
                    {"volume_rel_error", q.volume_rel_error},
                    {"min_volume_m3", q.min_volume},
                    {"median_volume_m3", q.median_volume},
                    {"min_volume_ratio", q.min_volume_ratio},
                    {"min_dihedral_deg", q.min_dihedral_deg},
                    {"median_dihedral_deg", q.median_dihedral_deg},
                    {"max_dihedral_deg", q.max_dihedral_deg},
                    {"median_radius_edge", q.median_radius_edge},
                    {"max_radius_edge", q.max_radius_edge}};
    nlohmann::json t = nlohmann::json::object();
    double total = 0;
    for (const auto& s : r->timings) {
      t[s.stage + "_ms"] = s.seconds * 1e3;
      total += s.seconds;
    }
    t["total_ms"] = total * 1e3;
    j["timings"] = t;
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << a.out << ": " << q.num_vertices << " vertices, " << q.num_tets
              << " tetrahedra, min dihedral " << q.min_dihedral_deg << " deg, "
              << (q.valid ? "valid" : "INVALID") << "\n";
  }
  if (!q.valid) {
    for (const auto& f : q.failures) std::cerr << "rheo mesh: check failed: " << f << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

void AddMeshCommand(CLI::App& app) {
  auto args = std::make_shared<MeshArgs>();
  CLI::App* cmd =
      app.add_subcommand("mesh", "sketch or contour -> Teddy solid -> tetrahedra (.vtu)");
  cmd->add_option("input", args->input,
                  "contour JSON ({\"contour\": [[x, y], ...]} in pixels) or a sketch (stroke JSON, "
                  "PNG, JPEG)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "output tetrahedra, VTK .vtu")->required();
  cmd->add_option("--thickness", args->thickness, "elevation scale (default 1)");
  cmd->add_option("--resolution", args->resolution, "target edge length [m] (default 0.008)");
  cmd->add_option("--pixel-size", args->pixel_size, "metres per pixel (default 2.5e-4)");
  cmd->add_option("--surface", args->surface, "also write the surface (.obj, .ply or .stl)");
  cmd->add_option("--svg", args->svg, "also write the 2D triangulation by class (.svg)");
  cmd->add_option("--division", args->division,
                  "2D cells under the columns: quality (default) or paper (Teddy's rows)")
      ->check(CLI::IsMember({"quality", "paper"}));
  cmd->add_flag("--json", args->json, "print counts, quality report and stage timings as JSON");
  cmd->callback([args] { g_exit_code = RunMesh(*args); });
}

}  // namespace rheo::tools
