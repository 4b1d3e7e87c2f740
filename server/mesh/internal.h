// Stages of BuildSolid, exposed for tests and benchmarks. Not a stable API.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "common/cancel.h"
#include "common/geometry.h"
#include "common/status.h"
#include "mesh/mesh.h"

namespace rheo::mesh::internal {

/// Pixels (y down) -> metres (y up); merges consecutive duplicates, makes it counter-clockwise and
/// refuses too few points, non-finite values and zero area.
Result<std::vector<Vec2>> ContourToMetres(const Polygon2& contour_px, double pixel_size);

/// Resamples a counter-clockwise polygon to even spacing <= `spacing` [m], halving the spacing
/// while the result self-intersects; falls back to the input, and refuses it (saying where, in
/// pixels) when that is not simple either. Never returns more points than the input has. Locating
/// the crossing for the message is quadratic; `cancel` stops it.
Result<std::vector<Vec2>> ResampleContour(const std::vector<Vec2>& polygon, double spacing,
                                          double pixel_size,
                                          const CancelToken& cancel = CancelToken());

bool IsSimplePolygon(const std::vector<Vec2>& polygon);

/// CDT with, per triangle edge i (opposite vertex i), the neighbouring triangle or -1 on the
/// contour.
struct Cdt {
  Triangulation2 tri;
  std::vector<std::array<int32_t, 3>> neighbors;  // (m)
};
Result<Cdt> TriangulateWithNeighbors(const std::vector<Vec2>& polygon);

/// Teddy: pruning, chordal axis, final triangulation, elevation (scaled by thickness).
Result<TeddyTriangulation> BuildTeddy(const Cdt& cdt, double thickness);

/// The inflated top surface z(x, y) >= 0 of a Teddy triangulation: quarter ovals from the contour
/// to the spine, linear along the spine.
class HeightField {
 public:
  explicit HeightField(const TeddyTriangulation& teddy);
  double operator()(const Vec2& p) const;  // [m]

 private:
  double Evaluate(int32_t tri, const Vec2& p) const;
  const TeddyTriangulation& t_;
  Vec2 lo_;
  double cell_ = 1;
  int nx_ = 1, ny_ = 1;
  std::vector<int32_t> start_;  // bucket offsets (nx*ny+1)
  std::vector<int32_t> items_;  // triangle ids per bucket
};

/// Quality 2D mesh of the polygon (angles >= ~20 degrees away from sharp contour corners, edges
/// <= size) without chords: no interior edge joins two contour vertices.
struct Mesh2 {
  Triangulation2 tri;
  std::vector<uint8_t> on_contour;  // (n)
};
Result<Mesh2> QualityMesh(const std::vector<Vec2>& polygon, double size);

/// The paper's cells: Teddy's triangles with spine-to-contour edges cut into rows <= spacing [m].
Result<Mesh2> PaperMesh(const TeddyTriangulation& teddy, double row_spacing);

struct ColumnLimits {
  int64_t max_vertices = 0;
  int64_t max_tets = 0;
};
/// Tetrahedra over the 2D mesh: each interior vertex carries a vertical column from -z to z cut
/// into layers of about `layer` [m]; each triangle's prism is swept bottom to top.
Result<TetMesh> BuildColumns(const Mesh2& mesh2, const std::vector<double>& heights, double layer,
                             const ColumnLimits& limits);

/// Moves vertices of tetrahedra whose smallest dihedral angle is under `threshold_deg` toward
/// their neighbours' centroid when that raises the smallest dihedral angle around them; at most
/// `sweeps` passes. Vertices on the surface with z != 0 stay on z = +-height(x, y) (none move
/// when `height` is empty); contour vertices (z = 0) stay put.
/// Stops between vertices (the mesh stays valid, partly improved) when `cancel` asks to.
void ImproveTets(TetMesh& mesh, double threshold_deg, int sweeps,
                 const std::function<double(const Vec2&)>& height,
                 const CancelToken& cancel = CancelToken());

}  // namespace rheo::mesh::internal
