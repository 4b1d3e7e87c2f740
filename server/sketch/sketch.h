// Sketch -> one closed, simple contour (paper sections 3.1-3.4). Pure: bytes in, result out.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/cancel.h"
#include "common/geometry.h"
#include "common/status.h"

namespace rheo::sketch {

/// How a picture is turned into ink and paper.
enum class Binarization {
  kAuto,      ///< global Otsu unless the paper brightness varies across the picture
  kOtsu,      ///< one global threshold (clean drawings, scans)
  kAdaptive,  ///< threshold against the local mean (photos of paper with uneven light)
};

/// Options of the contour extraction. Defaults suit 512 x 512 sketch-pad drawings.
struct ContourOptions {
  /// Vectorization tolerance epsilon of the recursive split [px]. Default 1.5.
  double epsilon_px = 1.5;
  /// Largest gap that is closed automatically, as a fraction of the outline perimeter. Default
  /// 0.03 (3 %).
  double max_gap_fraction = 0.03;
  /// Spacing of the resampled stroke polyline before vectorization [px]. Default 1.
  double resample_spacing_px = 1.0;
  /// Smallest enclosed area accepted as a shape to mesh [px^2]. Default 200.
  double min_area_px2 = 200.0;
  /// When true a self-crossing outline is split at the crossing and the larger loop kept (a
  /// repair); when false it is refused with the crossing point.
  bool repair_self_crossing = true;
  Binarization binarization = Binarization::kAuto;
  /// Window side of the adaptive threshold [px]; 0 picks 1/8 of the shorter picture side.
  int adaptive_window_px = 0;
  /// Adaptive threshold: ink when darker than the local mean by this fraction. Default 0.15.
  double adaptive_offset = 0.15;

  // Hard input limits; going over one is kResourceExhausted with the limit named.
  int64_t max_pixels = 16LL * 1024 * 1024;       ///< picture width x height [pixels]
  int64_t max_input_bytes = 32LL * 1024 * 1024;  ///< encoded picture or JSON size [bytes]
  int64_t max_stroke_points = 100000;            ///< points over all strokes
  int64_t max_strokes = 20000;                   ///< strokes of two or more distinct points
  /// Largest vectorized outline [points]; the self-crossing check and repair grow with it.
  int64_t max_contour_points = 20000;

  /// Checked inside every long loop; a stopped extraction returns kCancelled or
  /// kDeadlineExceeded. The default never stops.
  CancelToken cancel;
};

/// Where the sketch came from.
enum class SketchKind { kStrokes, kPng, kJpeg };

/// Time spent in one stage of the extraction.
struct StageTiming {
  std::string stage;  ///< e.g. "decode", "binarize", "thin", "vectorize"
  double ms = 0.0;    ///< wall time [ms]
};

/// The extracted outline and what was done to get it.
struct ContourResult {
  /// The outline in the input's pixel coordinates (x right, y down), closed implicitly, no
  /// repeated point. Counter-clockwise in the mathematical sense: the shoelace signed area of the
  /// coordinates as given is positive (on a y-down screen this is drawn clockwise).
  Polygon2 contour;
  double epsilon_px = 0.0;        ///< vectorization tolerance used [px]
  double line_distance_px = 0.0;  ///< largest distance from the drawn line to the contour [px]
  double area_px2 = 0.0;          ///< enclosed area of the contour [px^2]
  double perimeter_px = 0.0;      ///< perimeter of the contour [px]
  double line_width_px = 0.0;     ///< estimated width of the drawn line (0 for strokes) [px]
  SketchKind kind = SketchKind::kStrokes;
  int width = 0;                      ///< canvas or picture width [px]
  int height = 0;                     ///< canvas or picture height [px]
  bool filled_silhouette = false;     ///< picture held a filled shape; the contour is its edge
  std::string binarization;           ///< "otsu(t=128)" or "adaptive(w=64)"; empty for strokes
  std::vector<std::string> repairs;   ///< what was changed, with where
  std::vector<std::string> warnings;  ///< what was ignored, with where
  std::vector<StageTiming> timings;   ///< per stage, in order
};

/// Contour from stroke JSON: {"width": W, "height": H, "strokes": [[[x, y], ...], ...]}.
/// Overdrawn strokes are merged, gaps up to max_gap_fraction of the perimeter closed, the
/// polyline resampled and vectorized. Errors: kInvalidArgument (bad sketch, message says where),
/// kResourceExhausted (over max_stroke_points or max_input_bytes).
Result<ContourResult> ContourFromStrokesJson(std::string_view json, const ContourOptions& options);

/// Contour from a PNG or JPEG picture of dark ink on light paper: binarize, Hilditch thinning,
/// spur removal, pixel-chain tracing, recursive-split vectorization. A filled silhouette gives
/// its edge. Errors as for strokes; kResourceExhausted over max_pixels or max_input_bytes.
Result<ContourResult> ContourFromImage(std::span<const uint8_t> bytes,
                                       const ContourOptions& options);

/// Decodes a PNG or JPEG picture in full within `options`' limits (max_input_bytes, max_pixels)
/// and returns its width and height [px]: e.g. a background photo that sketch pads must be able
/// to show. kInvalidArgument for anything else or a broken file, kResourceExhausted over a limit.
Result<std::pair<int, int>> DecodePictureSize(std::span<const uint8_t> bytes,
                                              const ContourOptions& options);

/// Detects stroke JSON, PNG or JPEG by content and calls the matching function above.
Result<ContourResult> ContourFromSketchBytes(std::span<const uint8_t> bytes,
                                             const ContourOptions& options);

/// Symmetric Hausdorff distance between two closed polygons, sampled every sample_px [px].
double SymmetricHausdorff(const std::vector<Vec2>& a, const std::vector<Vec2>& b,
                          double sample_px = 0.25);

}  // namespace rheo::sketch
