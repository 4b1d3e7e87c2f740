// Contour -> constrained Delaunay triangulation -> Teddy solid -> tetrahedra (paper sections 3.5
// and 4), with a quality report measured on every mesh. Pure: no threads, files or logging.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "common/cancel.h"
#include "common/geometry.h"
#include "common/status.h"

namespace rheo::mesh {

/// Class of a triangle of the contour's constrained Delaunay triangulation, by the number of its
/// edges that lie on the contour (paper figure 7).
enum class TriangleClass : uint8_t {
  kJunction = 0,  // no contour edge
  kSleeve = 1,    // one contour edge
  kTerminal = 2,  // two contour edges
  kIsolated = 3,  // three contour edges: the contour is a single triangle
};

const char* TriangleClassName(TriangleClass c);

/// A 2D triangulation in metres (x right, y up).
struct Triangulation2 {
  std::vector<Vec2> points;                       // vertices (n) [m]
  std::vector<std::array<int32_t, 3>> triangles;  // counter-clockwise (m)
  std::vector<TriangleClass> classes;             // class of each triangle (m)
};

/// Teddy's final triangulation: contour vertices (height 0) and spine vertices (elevated), each
/// triangle typed by how many spine points it has (1, 2 or 3: paper figure 10).
struct TeddyTriangulation {
  std::vector<Vec2> points;                         // vertices (n) [m]
  std::vector<double> heights;                      // elevation of each vertex (n) [m]
  std::vector<uint8_t> is_spine;                    // 1 for spine vertices (n)
  std::vector<std::array<int32_t, 3>> triangles;    // counter-clockwise (m)
  std::vector<uint8_t> spine_count;                 // spine points of each triangle, 1..3 (m)
  std::vector<std::array<int32_t, 2>> spine_edges;  // the chordal axis (k)
  int32_t pruned_branches = 0;                      // terminal regions fanned by pruning
};

/// Measured validity and quality of a tetrahedral mesh.
struct QualityReport {
  bool valid = false;                 // every check below holds
  std::vector<std::string> failures;  // what failed, one line each
  int64_t num_vertices = 0;
  int64_t num_tets = 0;
  int64_t num_surface_faces = 0;
  int64_t num_nonpositive_tets = 0;       // tetrahedra with volume <= 0
  bool boundary_matches_surface = false;  // faces used by one tet == TetMesh::surface, oriented
  bool surface_closed = false;            // every surface edge shared by exactly two faces
  bool surface_manifold = false;          // every vertex link is one cycle
  bool surface_outward = false;           // consistent orientation, positive enclosed volume
  double tet_volume_sum = 0;              // [m^3]
  double surface_volume = 0;              // volume enclosed by the surface [m^3]
  double volume_rel_error = 0;            // |tet_volume_sum - surface_volume| / surface_volume
  double min_volume = 0;                  // [m^3]
  double median_volume = 0;               // [m^3]
  double min_volume_ratio = 0;            // min_volume / median_volume
  double min_dihedral_deg = 0;            // [deg]
  double median_dihedral_deg = 0;         // [deg]
  double max_dihedral_deg = 0;            // [deg]
  double median_radius_edge = 0;          // circumradius / shortest edge, median
  double max_radius_edge = 0;             // circumradius / shortest edge, worst
};

/// Wall time of one stage of BuildSolid.
struct StageTiming {
  std::string stage;
  double seconds = 0;  // [s]
};

/// Called between and inside stages; return false to cancel (BuildSolid then returns
/// ErrorCode::kCancelled). fraction in [0, 1] is the progress of the whole build.
using ProgressFn = std::function<bool(std::string_view stage, double fraction)>;

/// Which 2D cells carry the tetrahedral columns.
enum class Division : uint8_t {
  /// A quality Delaunay mesh of the outline (a hexagonal lattice inside, CGAL refinement along
  /// the contour: angles >= ~20 deg, edges <= resolution) lifted onto the Teddy surface.
  /// Default: about half the tetrahedra of kPaper for a better worst angle.
  kQuality = 0,
  /// The paper's cells: Teddy's final triangles cut into rows along the quarter ovals (figures
  /// 10-14). Its skinny fan and sleeve triangles are repaired by the smoothing that follows.
  kPaper = 1,
};

struct MeshOptions {
  /// Size of one contour unit (pixel) [m/px]. The default makes a 512 px drawing about 13 cm.
  double pixel_size = 2.5e-4;
  /// Scale of the spine elevation [-]; 1 gives Teddy's round cross-sections.
  double thickness = 1.0;
  /// Target edge length of the mesh, horizontally and through the thickness [m].
  double resolution = 0.008;
  Division division = Division::kQuality;
  /// Size limits; over a limit BuildSolid returns ErrorCode::kResourceExhausted naming it.
  int64_t max_contour_points = 100000;
  int64_t max_vertices = 2000000;
  int64_t max_tets = 10000000;
  /// Smallest solid: both sides of the contour's bounding box must be at least this [m]. Below
  /// it the tetrahedra are too small for the simulation's arithmetic (kInvalidArgument).
  double min_object_size = 1e-3;
  /// Smallest tetrahedron accepted [m^3]; a smaller one is refused (kInvalidArgument).
  double min_tet_volume = 1e-18;
  /// Optional progress / cancellation hook.
  ProgressFn progress;
  /// Checked between stages and inside the long loops; a stopped build returns kCancelled or
  /// kDeadlineExceeded. The CGAL triangulation and 2D mesher cannot be interrupted: their input
  /// is bounded instead (max_contour_points, and max_vertices through the 2D mesh estimate).
  CancelToken cancel;
};

struct MeshResult {
  TetMesh mesh;               // positively oriented tets, outward surface [m]
  Triangulation2 cdt;         // CDT of the (resampled) contour with triangle classes
  TeddyTriangulation teddy;   // pruned chordal axis, final triangulation, elevations
  Triangulation2 mesh2d;      // the 2D mesh under the tetrahedra (classes unused: kJunction)
  std::vector<Vec2> contour;  // the contour actually meshed, counter-clockwise [m]
  QualityReport quality;      // measured on `mesh`
  std::vector<StageTiming> timings;
};

/// Builds the tetrahedral solid of a closed contour given in pixels (y down, as the sketch stage
/// produces it). The result is in metres, y up, z through the thickness. Errors:
/// kInvalidArgument (fewer than 3 distinct points, non-finite coordinates, zero area,
/// self-intersection: the message says where), kResourceExhausted (a limit in options, named),
/// kCancelled (the progress hook returned false or `cancel` was cancelled), kDeadlineExceeded
/// (`cancel`'s deadline passed), kInternal (a broken invariant). A contour smaller than
/// min_object_size, or tetrahedra under min_tet_volume, are kInvalidArgument with the numbers.
Result<MeshResult> BuildSolid(const Polygon2& contour_px, const MeshOptions& options);

/// Runs every check of QualityReport on a tetrahedral mesh.
QualityReport CheckTetMesh(const TetMesh& mesh);

/// Constrained Delaunay triangulation of a simple polygon (any orientation, metres or pixels:
/// coordinates are used as given) with triangle classes. Consecutive duplicate points are merged;
/// exact predicates make near-collinear and cocircular input safe.
Result<Triangulation2> TriangulatePolygon(const std::vector<Vec2>& polygon);

// Exports as strings; the caller owns the files.
std::string SurfaceToObj(const TetMesh& mesh);
std::string SurfaceToPly(const TetMesh& mesh);
std::string SurfaceToStl(const TetMesh& mesh);
/// The CDT coloured by class, with Teddy's final triangulation and spine drawn over it.
std::string TriangulationToSvg(const MeshResult& result);

}  // namespace rheo::mesh
