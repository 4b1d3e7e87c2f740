// `rheoctl object create|list|get|delete|export`: stored objects made from sketches.
#include <cctype>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "rheo/client/channel.h"
#include "rheo/v1/objects.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

int ObjectCreate(const Global& g, const std::string& file, const std::string& name,
                 const rheo::v1::ContourOptions& co, const rheo::v1::MeshOptions& mo,
                 const std::string& background, bool add, bool json) {
  rheo::v1::CreateObjectRequest req;
  if (!LoadSketch(file, req.mutable_sketch())) return 3;
  if (!background.empty() &&
      !rheo::client::ReadWholeFile(background, *req.mutable_sketch()->mutable_background_image())) {
    std::cerr << "INVALID_ARGUMENT: cannot read " << background << "\n";
    return 3;
  }
  req.set_name(name);
  *req.mutable_contour_options() = co;
  *req.mutable_mesh_options() = mo;
  req.set_add_to_scene(add);
  auto stub = rheo::v1::ObjectService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g, 300.0);
  auto reader = stub->CreateObject(&ctx, req);
  rheo::v1::CreateObjectProgress p;
  rheo::v1::Object object;
  while (reader->Read(&p)) {
    if (p.has_object()) object = p.object();
    if (!json)
      std::fprintf(stderr, "%s %-15s %5.1f %%\n", p.job_id().c_str(), p.stage().c_str(),
                   100 * p.fraction());
  }
  grpc::Status s = reader->Finish();
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(object, true);
  } else {
    const auto& m = object.mesh();
    std::printf(
        "%s  %s: %u vertices, %u tetrahedra, %u surface triangles, volume %.3g m^3, "
        "min dihedral %.1f deg, watertight %s\n",
        object.id().c_str(), object.name().c_str(), m.vertex_count(), m.tetrahedron_count(),
        m.surface_triangle_count(), m.volume(), m.min_dihedral_deg(),
        m.watertight() ? "yes" : "no");
  }
  return 0;
}

int ObjectList(const Global& g, bool json) {
  auto stub = rheo::v1::ObjectService::NewStub(Connect(g));
  std::string token;
  do {
    grpc::ClientContext ctx;
    SetDeadline(ctx, g);
    rheo::v1::ListObjectsRequest req;
    req.set_page_token(token);
    rheo::v1::ListObjectsResponse resp;
    grpc::Status s = stub->ListObjects(&ctx, req, &resp);
    if (!s.ok()) return Fail(s);
    for (const auto& o : resp.objects()) {
      if (json) {
        std::cout << ToJson(o, false) << "\n";
      } else {
        std::printf("%s  %-24s %8u tets  %.3g m^3\n", o.id().c_str(), o.name().c_str(),
                    o.mesh().tetrahedron_count(), o.mesh().volume());
      }
    }
    token = resp.next_page_token();
  } while (!token.empty());
  return 0;
}

int ObjectGet(const Global& g, const std::string& id) {
  rheo::v1::GetObjectRequest req;
  req.set_id(id);
  rheo::v1::Object o;
  grpc::Status s =
      Unary<rheo::v1::ObjectService>(g, &rheo::v1::ObjectService::Stub::GetObject, req, &o);
  if (!s.ok()) return Fail(s);
  std::cout << ToJson(o, true);
  return 0;
}

int ObjectDelete(const Global& g, const std::string& id) {
  rheo::v1::DeleteObjectRequest req;
  req.set_id(id);
  rheo::v1::DeleteObjectResponse r;
  grpc::Status s =
      Unary<rheo::v1::ObjectService>(g, &rheo::v1::ObjectService::Stub::DeleteObject, req, &r);
  return s.ok() ? 0 : Fail(s);
}

int ObjectExport(const Global& g, const std::string& id, const std::string& format,
                 const std::string& out_path) {
  rheo::v1::ExportFormat f;
  std::string upper = "EXPORT_FORMAT_";
  for (char c : format) upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (!rheo::v1::ExportFormat_Parse(upper, &f)) {
    std::cerr
        << "INVALID_ARGUMENT: --format must be vtu, obj, ply, stl, svg, sketch or background\n";
    return 3;
  }
  auto stub = rheo::v1::ObjectService::NewStub(Connect(g));
  grpc::ClientContext ctx;
  SetDeadline(ctx, g);
  rheo::v1::ExportObjectRequest req;
  req.set_id(id);
  req.set_format(f);
  auto reader = stub->ExportObject(&ctx, req);
  std::string data;
  rheo::v1::ExportChunk c;
  while (reader->Read(&c)) data += c.data();
  grpc::Status s = reader->Finish();
  if (!s.ok()) return Fail(s);
  if (out_path.empty() || out_path == "-") {
    std::cout << data;
  } else {
    std::ofstream out(out_path, std::ios::binary);
    out << data;
    if (!out) {
      std::cerr << "cannot write " << out_path << "\n";
      return 1;
    }
  }
  return 0;
}

}  // namespace

void AddObjectCommand(CLI::App& app, const Global& g) {
  struct ObjectArgs {
    std::string file, name, id, format = "vtu", out_path, background;
    bool add = false;
    bool json = false;
    double epsilon = 0, thickness = 0, resolution = 0, pixel_size = 0;
  };
  auto a = std::make_shared<ObjectArgs>();
  auto* object = app.add_subcommand("object", "stored objects made from sketches");
  object->require_subcommand(1);
  auto* create = object->add_subcommand(
      "create", "sketch (JSON strokes, contour JSON, PNG, JPEG) -> stored solid");
  create->add_option("FILE", a->file, "sketch file")->required()->check(CLI::ExistingFile);
  create->add_option("--name", a->name, "label");
  create->add_option("--epsilon", a->epsilon, "vectorization tolerance [px]");
  create->add_option("--thickness", a->thickness, "elevation scale (default 1)");
  create->add_option("--resolution", a->resolution, "target edge length [m]");
  create->add_option("--pixel-size", a->pixel_size, "size of a sketch pixel [m/px]");
  create->add_option("--background", a->background, "background photo to store with the object")
      ->check(CLI::ExistingFile);
  create->add_flag("--add", a->add, "add the object to the scene when stored");
  create->add_flag("--json", a->json, "print the Object as JSON");
  create->callback([&g, a] {
    rheo::v1::ContourOptions co;
    co.set_epsilon_px(a->epsilon);
    rheo::v1::MeshOptions mo;
    mo.set_thickness(a->thickness);
    mo.set_resolution(a->resolution);
    mo.set_pixel_size(a->pixel_size);
    g_exit_code = ObjectCreate(g, a->file, a->name, co, mo, a->background, a->add, a->json);
  });
  auto* list = object->add_subcommand("list", "stored objects, newest first");
  list->add_flag("--json", a->json, "one JSON line per object");
  list->callback([&g, a] { g_exit_code = ObjectList(g, a->json); });
  auto* get = object->add_subcommand("get", "one object as JSON");
  get->add_option("ID", a->id)->required();
  get->callback([&g, a] { g_exit_code = ObjectGet(g, a->id); });
  auto* del = object->add_subcommand("delete", "delete a stored object");
  del->add_option("ID", a->id)->required();
  del->callback([&g, a] { g_exit_code = ObjectDelete(g, a->id); });
  auto* exp = object->add_subcommand("export", "write an object's mesh, sketch or picture");
  exp->add_option("ID", a->id)->required();
  exp->add_option("--format", a->format, "vtu, obj, ply, stl, svg, sketch, background")
      ->capture_default_str();
  exp->add_option("--out", a->out_path, "output file (default stdout)");
  exp->callback([&g, a] { g_exit_code = ObjectExport(g, a->id, a->format, a->out_path); });
}

}  // namespace rheoctl
