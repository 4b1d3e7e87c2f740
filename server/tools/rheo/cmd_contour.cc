// `rheo contour INPUT [--epsilon PX] [--json] [--svg OUT.svg]`: sketch file -> contour.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "sketch/sketch.h"

namespace rheo::tools {
namespace {

struct ContourArgs {
  std::string input;
  double epsilon = rheo::sketch::ContourOptions{}.epsilon_px;
  bool json = false;
  std::string svg;
  double max_gap = rheo::sketch::ContourOptions{}.max_gap_fraction;
  std::string binarize = "auto";
};

std::string Base64(const std::string& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (uint8_t(in[i]) << 16) | (uint8_t(in[i + 1]) << 8) | uint8_t(in[i + 2]);
    out += k[v >> 18], out += k[(v >> 12) & 63], out += k[(v >> 6) & 63], out += k[v & 63];
  }
  if (i + 1 == in.size()) {
    const unsigned v = uint8_t(in[i]) << 16;
    out += k[v >> 18], out += k[(v >> 12) & 63], out += "==";
  } else if (i + 2 == in.size()) {
    const unsigned v = (uint8_t(in[i]) << 16) | (uint8_t(in[i + 1]) << 8);
    out += k[v >> 18], out += k[(v >> 12) & 63], out += k[(v >> 6) & 63], out += '=';
  }
  return out;
}

std::string Svg(const std::string& data, const rheo::sketch::ContourResult& r) {
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" "
    << "width=\"" << r.width << "\" height=\"" << r.height << "\" viewBox=\"0 0 " << r.width << ' '
    << r.height << "\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  if (r.kind == rheo::sketch::SketchKind::kStrokes) {
    auto j = nlohmann::json::parse(data, nullptr, false);
    if (!j.is_discarded() && j.contains("strokes")) {
      for (const auto& stroke : j["strokes"]) {
        s << "<polyline fill=\"none\" stroke=\"#888\" stroke-width=\"3\" points=\"";
        for (const auto& p : stroke) s << p[0].get<double>() << ',' << p[1].get<double>() << ' ';
        s << "\"/>\n";
      }
    }
  } else {
    const char* mime = r.kind == rheo::sketch::SketchKind::kPng ? "image/png" : "image/jpeg";
    s << "<image width=\"" << r.width << "\" height=\"" << r.height << "\" opacity=\"0.5\" "
      << "xlink:href=\"data:" << mime << ";base64," << Base64(data) << "\"/>\n";
  }
  s << "<polygon fill=\"rgba(255,0,0,0.08)\" stroke=\"red\" stroke-width=\"1\" points=\"";
  for (const auto& p : r.contour.points) s << p.x() << ',' << p.y() << ' ';
  s << "\"/>\n";
  for (const auto& p : r.contour.points) {
    s << "<circle cx=\"" << p.x() << "\" cy=\"" << p.y() << "\" r=\"1.5\" fill=\"blue\"/>\n";
  }
  s << "</svg>\n";
  return s.str();
}

void Run(const ContourArgs& a) {
  std::ifstream f(a.input, std::ios::binary);
  if (!f) {
    std::cerr << "rheo contour: cannot open " << a.input << "\n";
    g_exit_code = 1;
    return;
  }
  std::ostringstream buf;
  buf << f.rdbuf();
  const std::string data = buf.str();
  rheo::sketch::ContourOptions o;
  o.epsilon_px = a.epsilon;
  o.max_gap_fraction = a.max_gap;
  if (a.binarize == "otsu") o.binarization = rheo::sketch::Binarization::kOtsu;
  if (a.binarize == "adaptive") o.binarization = rheo::sketch::Binarization::kAdaptive;
  auto r = rheo::sketch::ContourFromSketchBytes(
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(data.data()), data.size()), o);
  if (!r.ok()) {
    std::cerr << "rheo contour: " << a.input << ": " << r.error().message << " ("
              << rheo::ErrorCodeName(r.error().code) << ")\n";
    g_exit_code = r.error().code == rheo::ErrorCode::kInternal ? 2 : 1;
    return;
  }
  if (a.json) {
    nlohmann::json j;
    j["contour"] = nlohmann::json::array();
    for (const auto& p : r->contour.points) j["contour"].push_back({p.x(), p.y()});
    j["epsilon"] = r->epsilon_px;
    j["line_distance_px"] = r->line_distance_px;
    j["area_px2"] = r->area_px2;
    j["line_width_px"] = r->line_width_px;
    j["filled_silhouette"] = r->filled_silhouette;
    if (!r->binarization.empty()) j["binarization"] = r->binarization;
    j["warnings"] = r->warnings;
    j["repairs"] = r->repairs;
    j["timings_ms"] = nlohmann::json::object();
    for (const auto& t : r->timings) j["timings_ms"][t.stage] = t.ms;
    std::cout << j.dump(1) << "\n";
  } else {
    std::printf("contour: %zu points, area %.0f px^2, epsilon %.2f px, line distance %.2f px\n",
                r->contour.points.size(), r->area_px2, r->epsilon_px, r->line_distance_px);
    for (const auto& m : r->repairs) std::printf("repair: %s\n", m.c_str());
    for (const auto& m : r->warnings) std::printf("warning: %s\n", m.c_str());
    double total = 0;
    for (const auto& t : r->timings)
      std::printf("  %-11s %8.3f ms\n", t.stage.c_str(), t.ms), total += t.ms;
    std::printf("  %-11s %8.3f ms\n", "total", total);
  }
  if (!a.svg.empty()) {
    std::ofstream out(a.svg);
    out << Svg(data, *r);
    if (!out) {
      std::cerr << "rheo contour: cannot write " << a.svg << "\n";
      g_exit_code = 2;
    }
  }
}

}  // namespace

void AddContourCommand(CLI::App& app) {
  auto args = std::make_shared<ContourArgs>();
  CLI::App* cmd = app.add_subcommand("contour", "Sketch (stroke JSON, PNG or JPEG) -> contour");
  cmd->add_option("INPUT", args->input, "sketch file")->required();
  cmd->add_option("--epsilon", args->epsilon, "vectorization tolerance [px]")
      ->check(CLI::Range(1e-3, 1000.0));
  cmd->add_flag("--json", args->json, "print the result as JSON");
  cmd->add_option("--svg", args->svg, "write the input with the contour over it");
  cmd->add_option("--max-gap", args->max_gap, "largest gap closed, fraction of the perimeter")
      ->check(CLI::Range(0.0, 0.5));
  cmd->add_option("--binarize", args->binarize, "auto, otsu or adaptive")
      ->check(CLI::IsMember({"auto", "otsu", "adaptive"}));
  cmd->callback([args] { Run(*args); });
}

}  // namespace rheo::tools
