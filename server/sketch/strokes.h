// Stroke input: JSON decoding with bounded memory, and merging strokes into closed outlines.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/geometry.h"
#include "common/status.h"
#include "sketch/sketch.h"

namespace rheo::sketch::internal {

struct StrokeSet {
  int width = 0;                           // canvas width [px]
  int height = 0;                          // canvas height [px]
  std::vector<std::vector<Vec2>> strokes;  // strokes (s), each a polyline of points [px]
};

/// Parses {"width": W, "height": H, "strokes": [[[x, y], ...], ...]} in one forward pass (no
/// document tree); memory is a few times the text, which max_input_bytes bounds, plus the points,
/// which max_stroke_points bounds.
Result<StrokeSet> ParseStrokesJson(std::string_view json, const ContourOptions& options);

/// A closed outline merged from strokes, before vectorization.
struct MergedOutline {
  std::vector<Vec2> closed;  // the outline polyline, closed implicitly [px]
  std::vector<std::string> repairs;
  std::vector<std::string> warnings;
};

/// Orders and joins strokes (trimming overdrawn ends), closes gaps up to max_gap_fraction of the
/// perimeter, keeps the largest closed outline and names the ignored ones.
Result<MergedOutline> MergeStrokes(const StrokeSet& set, const ContourOptions& options);

}  // namespace rheo::sketch::internal
