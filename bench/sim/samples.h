// The project's sketched samples (samples/NAME.json) meshed at chosen sizes, for the benchmarks.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"

namespace sim_bench {

/// A project sample meshed at about each target tet count.
struct SampleMeshes {
  std::vector<rheo::TetMesh> meshes;
  std::vector<double> resolution;  // the edge length asked of the mesher [m]
};
/// Each mesh's lowest point is on the floor (y = 0).
rheo::Result<SampleMeshes> MeshSample(const std::string& sample, std::span<const int> targets);
/// At about 5k, 20k and 100k tets, those not above `max_tets`.
rheo::Result<SampleMeshes> MeshSampleSizes(const std::string& sample, int max_tets);

}  // namespace sim_bench
