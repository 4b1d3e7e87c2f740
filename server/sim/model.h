// The fixed part of a simulated object (like MuJoCo's mjModel): topology, rest geometry and masses,
// built once from a TetMesh. Nothing here changes while stepping.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"

namespace rheo::sim {

struct Model {
  int32_t num_nodes = 0;
  std::vector<Vec3> rest_positions;  // node rest positions (n) [m]
  std::vector<double> node_volume;   // lumped volume share, a quarter of each tet (n) [m^3]
  std::vector<double> mass;          // lumped masses = density * node_volume (n) [kg]
  std::vector<double> inv_mass;      // 1 / mass, 0 for fixed nodes (n) [1/kg]
  std::vector<uint8_t> fixed;        // 1 = node held in place (n)

  std::vector<std::array<int32_t, 2>> edges;  // unique tet edges, i < j (e)
  std::vector<double> edge_rest_length;       // (e) [m]

  std::vector<std::array<int32_t, 3>> faces;  // boundary triangles, outward (k)
  std::vector<double> face_rest_area;         // (k) [m^2]
  std::vector<double> face_min_height;        // smallest triangle height (k) [m]

  std::vector<std::array<int32_t, 4>> tets;  // positively oriented tetrahedra (m)
  std::vector<double> tet_rest_volume;       // (m) [m^3]
  std::vector<double> tet_min_height;        // smallest tet height (m) [m]
  // Half the smallest face's |6 grad V| at rest (= its area): the eq. 6 kernel divides a corner's
  // volume gradient by no less, so a face that collapses does not turn the unit direction's
  // derivative (1/|grad V|) into an unbounded stiffness (m) [m^2].
  std::vector<float> tet_grad_floor;

  // The tets and faces at each edge, for the assembled product of the implicit system (CSR: edge
  // k's entries are [start[k], start[k + 1])). An entry is 16 t + 4 q + r for element t whose
  // corners q and r (0-3) are the edge's first and second node. A pair of fixed nodes that is not
  // an edge has no entry (its block would only touch rows the solve leaves out); all four are
  // empty when any other pair of an element's nodes is not an edge (only in a model built from
  // parts). IndexElementsByEdge rebuilds them after `fixed` changes.
  std::vector<int32_t> edge_tet_start, edge_tet;
  std::vector<int32_t> edge_face_start, edge_face;

  double rest_volume = 0.0;   // volume enclosed by the faces at rest [m^3]
  double size = 0.0;          // bounding-box diagonal at rest [m]
  int32_t inverted_tets = 0;  // tets with non-positive rest volume (kept; eq. 6 skips them)
};

/// Builds the model from a tetrahedral mesh. Refuses (INVALID_ARGUMENT, saying which element)
/// out-of-range indices, non-finite positions, zero-length edges and empty meshes. Tets with
/// negative orientation are flipped; the surface is taken from mesh.surface, or rebuilt when empty.
Result<Model> BuildModel(const TetMesh& mesh, double density);

/// Rebuilds the edge -> element lists (see edge_tet_start) from the model's elements, edges and
/// fixed nodes: after a caller fixes nodes whose pairs are not all edges (a multi-rate patch's
/// boundary). Allocates.
void IndexElementsByEdge(Model& model);

/// Builds a model from explicit parts (used for single-element tests): node masses are given
/// directly and no tetrahedron is required.
Result<Model> BuildModelFromParts(std::span<const Vec3> positions, std::span<const double> masses,
                                  std::span<const std::array<int32_t, 2>> edges,
                                  std::span<const std::array<int32_t, 3>> faces,
                                  std::span<const std::array<int32_t, 4>> tets);

}  // namespace rheo::sim
