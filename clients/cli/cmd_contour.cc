// `rheoctl contour FILE`: the contour of a sketch as the daemon extracts it (nothing stored).
#include <iostream>

#include "rheo/v1/objects.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

int Contour(const Global& g, const std::string& file, const rheo::v1::ContourOptions& co) {
  rheo::v1::ExtractContourRequest req;
  if (!LoadSketch(file, req.mutable_sketch())) return 3;
  *req.mutable_options() = co;
  rheo::v1::ContourReport r;
  grpc::Status s =
      Unary<rheo::v1::ObjectService>(g, &rheo::v1::ObjectService::Stub::ExtractContour, req, &r);
  if (!s.ok()) return Fail(s);
  std::cout << ToJson(r, true);
  return 0;
}

}  // namespace

void AddContourCommand(CLI::App& app, const Global& g) {
  struct ContourArgs {
    std::string file;
    double epsilon = 0;
  };
  auto a = std::make_shared<ContourArgs>();
  auto* contour = app.add_subcommand("contour", "extract the contour of a sketch (nothing stored)");
  contour->add_option("FILE", a->file, "sketch file")->required()->check(CLI::ExistingFile);
  contour->add_option("--epsilon", a->epsilon, "vectorization tolerance [px]");
  contour->callback([&g, a] {
    rheo::v1::ContourOptions co;
    co.set_epsilon_px(a->epsilon);
    g_exit_code = Contour(g, a->file, co);
  });
}

}  // namespace rheoctl
