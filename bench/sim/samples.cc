// The project's sketched samples meshed at chosen sizes, for sim_bench and tick_cost_bench.
#include "samples.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "mesh/mesh.h"
#include "sketch/sketch.h"

namespace sim_bench {

using rheo::TetMesh;
using rheo::Vec3;

rheo::Result<SampleMeshes> MeshSample(const std::string& sample, std::span<const int> targets) {
  const std::string path = std::string(RHEO_SAMPLES_DIR) + "/" + sample + ".json";
  std::ifstream in(path, std::ios::binary);
  if (!in) return rheo::NotFound("cannot read " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  auto contour = rheo::sketch::ContourFromSketchBytes(
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()),
      rheo::sketch::ContourOptions{});
  if (!contour.ok()) return contour.error();
  SampleMeshes out;
  const double r0 = 0.008, n0 = 2673.0;  // the bean at 8 mm (rheo mesh); a first guess
  for (int target : targets) {
    // The edge length for about `target` tets: a first guess from the bean at 8 mm, then once
    // more from the count it gave.
    rheo::mesh::MeshOptions opt;
    opt.resolution = r0 * std::cbrt(n0 / target);
    auto solid = rheo::mesh::BuildSolid(contour->contour, opt);
    if (solid.ok()) {
      opt.resolution *= std::cbrt(double(solid->mesh.tets.size()) / target);
      solid = rheo::mesh::BuildSolid(contour->contour, opt);
    }
    if (!solid.ok()) return solid.error();
    // The mesher leaves the solid where its sketch was (the bean at y = -0.095 to -0.048 m):
    // its lowest point goes onto the floor (y = 0). Until 2026-12-03 it did not, and every
    // sketched run started with the whole object under the floor.
    TetMesh& mesh = solid->mesh;
    double lowest = 1e30;
    for (const Vec3& x : mesh.positions) lowest = std::min(lowest, x.y());
    for (Vec3& x : mesh.positions) x.y() -= lowest;
    out.meshes.push_back(std::move(mesh));
    out.resolution.push_back(opt.resolution);
  }
  return out;
}

rheo::Result<SampleMeshes> MeshSampleSizes(const std::string& sample, int max_tets) {
  std::vector<int> targets;
  for (int target : {5000, 20000, 100000})
    if (target <= max_tets) targets.push_back(target);
  return MeshSample(sample, targets);
}

}  // namespace sim_bench
