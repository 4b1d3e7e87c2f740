#include "sketch/sketch.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <memory>
#include <optional>

#include "sketch/format.h"
#include "sketch/polyline.h"
#include "sketch/raster.h"
#include "sketch/strokes.h"

namespace rheo::sketch {
namespace {

using internal::Bitmap;
using internal::Num;
using internal::Pt;

class Stopwatch {
 public:
  void Lap(const char* stage, ContourResult& r) {
    const auto now = std::chrono::steady_clock::now();
    r.timings.push_back({stage, std::chrono::duration<double, std::milli>(now - t_).count()});
    t_ = now;
  }

 private:
  std::chrono::steady_clock::time_point t_ = std::chrono::steady_clock::now();
};

Status CheckOptions(const ContourOptions& o) {
  if (!(o.epsilon_px > 0.0 && o.epsilon_px <= 1000.0)) {
    return InvalidArgument("epsilon must be in (0, 1000] px, got " + Num(o.epsilon_px, 3));
  }
  if (!(o.max_gap_fraction >= 0.0 && o.max_gap_fraction <= 0.5)) {
    return InvalidArgument("max_gap_fraction must be in [0, 0.5], got " +
                           Num(o.max_gap_fraction, 3));
  }
  if (!(o.resample_spacing_px > 0.0 && o.resample_spacing_px <= 100.0)) {
    return InvalidArgument("resample_spacing_px must be in (0, 100], got " +
                           Num(o.resample_spacing_px, 3));
  }
  if (!(o.adaptive_offset > 0.0 && o.adaptive_offset < 1.0)) {
    return InvalidArgument("adaptive_offset must be in (0, 1)");
  }
  return Status::Ok();
}

// Vectorizes a dense closed chain, repairs or refuses self-crossings, orients it and checks size.
Status Finish(std::vector<Vec2> chain, const ContourOptions& o, ContourResult& r) {
  internal::RemoveNearDuplicates(chain, 1e-6);
  Eigen::AlignedBox2d box;
  for (const Vec2& p : chain) box.extend(p);
  if (chain.size() < 3) {
    return InvalidArgument("shape too small to mesh: the outline at " +
                           (chain.empty() ? std::string("?") : Pt(chain[0])) + " has " +
                           std::to_string(chain.size()) + " distinct points");
  }
  double hmax = 0.0;
  const std::vector<int> idx = internal::SimplifyClosed(chain, o.epsilon_px, &hmax, o.cancel);
  if (Status s = o.cancel.Check("vectorization"); !s) return s;
  if (static_cast<int64_t>(idx.size()) > o.max_contour_points) {
    return ResourceExhausted("the outline vectorizes to " + std::to_string(idx.size()) +
                             " points, over the limit of " + std::to_string(o.max_contour_points) +
                             " (max_contour_points); draw a simpler outline or raise epsilon");
  }
  std::vector<Vec2> poly;
  poly.reserve(idx.size());
  for (int i : idx) poly.push_back(chain[i]);
  bool repaired = false;
  for (int guard = 0; guard < 1000; ++guard) {
    const auto x = internal::FindSelfCrossing(poly, o.cancel);
    if (Status s = o.cancel.Check("the self-crossing check"); !s) return s;
    if (!x) break;
    if (!o.repair_self_crossing) {
      return InvalidArgument("self-crossing outline at " + Pt(x->point) + " (edges " +
                             std::to_string(x->edge_a) + " and " + std::to_string(x->edge_b) +
                             " of the vectorized outline)");
    }
    // Two loops meet at the crossing; keep the one with the larger area.
    std::vector<Vec2> inner = {x->point}, outer = {x->point};
    for (int k = x->edge_a + 1; k <= x->edge_b; ++k) inner.push_back(poly[k]);
    for (int k = x->edge_b + 1; k < static_cast<int>(poly.size()); ++k) outer.push_back(poly[k]);
    for (int k = 0; k <= x->edge_a; ++k) outer.push_back(poly[k]);
    internal::RemoveNearDuplicates(inner, 1e-6);
    internal::RemoveNearDuplicates(outer, 1e-6);
    const double ai = std::abs(internal::SignedArea(inner));
    const double ao = std::abs(internal::SignedArea(outer));
    const bool keep_inner = ai > ao;
    r.repairs.push_back("self-crossing at " + Pt(x->point) +
                        ": kept the larger loop, dropped a loop of area " +
                        Num(keep_inner ? ao : ai, 0) + " px^2");
    poly = keep_inner ? std::move(inner) : std::move(outer);
    repaired = true;
    if (poly.size() < 3) break;
  }
  if (poly.size() < 3) {
    return InvalidArgument("shape too small to mesh: the outline in " + Pt(box.min()) + "-" +
                           Pt(box.max()) + " vectorizes to fewer than 3 points at epsilon " +
                           Num(o.epsilon_px, 2) + " px");
  }
  double area = internal::SignedArea(poly);
  if (area < 0) {
    std::reverse(poly.begin(), poly.end());
    area = -area;
  }
  if (area < o.min_area_px2) {
    return InvalidArgument("shape too small to mesh: area " + Num(area, 0) + " px^2 in " +
                           Pt(box.min()) + "-" + Pt(box.max()) + ", below min_area " +
                           Num(o.min_area_px2, 0) + " px^2");
  }
  if (repaired) {
    // Distance of the kept part of the drawn line to the final contour.
    hmax = internal::MaxNearDistance(chain, poly, 3.0 * o.epsilon_px + 2.0, o.cancel);
    if (Status s = o.cancel.Check("vectorization"); !s) return s;
  }
  r.contour.points = std::move(poly);
  r.epsilon_px = o.epsilon_px;
  r.line_distance_px = hmax;
  r.area_px2 = area;
  r.perimeter_px = internal::ClosedLength(r.contour.points);
  return Status::Ok();
}

}  // namespace

// Most points the resampled stroke outline may have (a 4096 px canvas's border is 16,384 px).
constexpr int kMaxResampledPoints = 50000;

Result<ContourResult> ContourFromStrokesJson(std::string_view json, const ContourOptions& o) {
  if (Status s = CheckOptions(o); !s) return s.error();
  ContourResult r;
  r.kind = SketchKind::kStrokes;
  Stopwatch sw;
  auto set = internal::ParseStrokesJson(json, o);
  if (!set.ok()) return set.error();
  r.width = set->width;
  r.height = set->height;
  sw.Lap("parse", r);
  if (Status s = o.cancel.Check("stroke parsing"); !s) return s.error();
  auto merged = internal::MergeStrokes(*set, o);
  if (!merged.ok()) return merged.error();
  r.repairs = std::move(merged->repairs);
  r.warnings = std::move(merged->warnings);
  sw.Lap("merge", r);
  // The work after this point grows with the outline's length in pixels, which the input's
  // point count does not bound (two far-apart points make a long outline): cap the samples.
  double spacing = o.resample_spacing_px;
  const double length = internal::ClosedLength(merged->closed);
  if (length > kMaxResampledPoints * spacing) {
    spacing = length / kMaxResampledPoints;
    r.warnings.push_back("the outline is " + Num(length, 0) + " px long: resampled every " +
                         Num(spacing, 2) + " px instead of " + Num(o.resample_spacing_px, 2) +
                         " px to keep it to " + std::to_string(kMaxResampledPoints) + " points");
  }
  std::vector<Vec2> dense = internal::ResampleClosed(merged->closed, spacing);
  sw.Lap("resample", r);
  if (Status s = o.cancel.Check("resampling"); !s) return s.error();
  if (Status s = Finish(std::move(dense), o, r); !s) return s.error();
  sw.Lap("vectorize", r);
  return r;
}

namespace {

// Values in the analysis bitmap.
constexpr uint8_t kBg = 0, kInk = 1, kOutside = 2, kInkSeen = 3, kHoleSeen = 4;

struct Component {
  int64_t area = 0;                                  // ink pixels
  int64_t boundary = 0;                              // ink pixels with a non-ink 4-neighbour
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;  // bounding box, padded coordinates
  std::vector<int> holes;
  size_t first_pixel = 0;        // range in the ink pixel list
  int64_t hole_area = 0;         // all holes [px]
  int64_t significant_area = 0;  // holes that are not slivers inside the line [px]
  int significant = 0;
  int64_t largest_hole = 0;
  enum Kind { kSpeck, kOutline, kSilhouette, kOpen } kind = kSpeck;
  double Width() const { return boundary > 0 ? 2.0 * area / boundary : 1.0; }
};

struct Hole {
  int64_t area = 0;
  int64_t perimeter = 0;  // 4-neighbour edges to ink
  int parent = -1;
  bool significant = false;
  size_t first_span = 0, spans = 0;  // range in the span list
};

struct Span {
  int row;  // index of the row's first padded pixel
  int xl, xr;
};

std::string Box(const Component& c) {
  return Pt(Vec2(c.x0 - 1, c.y0 - 1)) + "-" + Pt(Vec2(c.x1 - 1, c.y1 - 1));
}

// Bresenham line of ink in a bitmap (inner coordinates).
void DrawLine(Bitmap& bm, int x0, int y0, int x1, int y1) {
  const int dx = std::abs(x1 - x0), sx = x0 < x1 ? 1 : -1;
  const int dy = -std::abs(y1 - y0), sy = y0 < y1 ? 1 : -1;
  int err = dx + dy;
  for (;;) {
    bm.at(x0, y0) = 1;
    if (x0 == x1 && y0 == y1) break;
    const int e2 = 2 * err;
    if (e2 >= dy) err += dy, x0 += sx;
    if (e2 <= dx) err += dx, y0 += sy;
  }
}

// Farthest skeleton pixel from `from` (8-connected hops); returns it and its distance.
std::pair<int, int> Farthest(const Bitmap& bm, int from, std::vector<int>& dist) {
  const int s = bm.stride;
  const int off[8] = {-s - 1, -s, -s + 1, -1, 1, s - 1, s, s + 1};
  std::fill(dist.begin(), dist.end(), -1);
  std::vector<int> queue = {from};
  dist[from] = 0;
  int best = from;
  for (size_t q = 0; q < queue.size(); ++q) {
    const int i = queue[q];
    if (dist[i] > dist[best]) best = i;
    for (int d : off) {
      const int j = i + d;
      if (bm.v[j] && dist[j] < 0) dist[j] = dist[i] + 1, queue.push_back(j);
    }
  }
  return {best, dist[best]};
}

// The picture's format from its signature, decoded to grey; sets r.kind, r.width, r.height.
Result<internal::GrayImage> Decode(std::span<const uint8_t> bytes, const ContourOptions& o,
                                   ContourResult& r) {
  Result<internal::GrayImage> img = InvalidArgument("");
  if (internal::LooksLikePng(bytes)) {
    r.kind = SketchKind::kPng;
    img = internal::DecodePng(bytes, o);
  } else if (internal::LooksLikeJpeg(bytes)) {
    r.kind = SketchKind::kJpeg;
    img = internal::DecodeJpeg(bytes, o);
  } else {
    return InvalidArgument("not a PNG or JPEG picture (unknown signature)");
  }
  if (!img.ok()) return img.error();
  r.width = img->width;
  r.height = img->height;
  return img;
}

// The binarized picture's parts: ink components with their pixels, and the holes in them with
// their spans of paper.
struct Components {
  int stride = 0;  // of the bitmap the pixel indices refer to
  std::vector<Component> comps;
  std::vector<Hole> holes;
  std::vector<Span> spans;
  std::vector<int> ink;  // pixels of every component, component after component
};

// Components: outside paper, ink components (8-connected), holes (4-connected paper inside).
// Marks every pixel of `bm` as seen.
Components FindComponents(Bitmap& bm) {
  Components out;
  const int s = bm.stride;
  out.stride = s;
  uint8_t* v = bm.v.data();
  const size_t npx = bm.v.size();
  // Component id per ink pixel; only ink pixels are written, so the pages of paper stay untouched.
  std::unique_ptr<int32_t[]> label(new int32_t[npx]);
  internal::SpanFill<false>(bm, 0, kBg, kOutside, [](int, int, int, int) {});
  std::vector<Component>& comps = out.comps;
  std::vector<Hole>& holes = out.holes;
  std::vector<Span>& spans = out.spans;
  std::vector<int>& ink = out.ink;
  std::vector<int> stack;
  const int off8[8] = {-s - 1, -s, -s + 1, -1, 1, s - 1, s, s + 1};
  const int off4[4] = {-s, -1, 1, s};
  auto visit = [&](int i) {
    if (v[i] == kInk) {
      const int id = static_cast<int>(comps.size());
      comps.emplace_back();
      Component& c = comps.back();
      c.first_pixel = ink.size();
      stack.assign(1, i);
      v[i] = kInkSeen;
      while (!stack.empty()) {
        const int p = stack.back();
        stack.pop_back();
        label[p] = id;
        ink.push_back(p);
        ++c.area;
        const int x = p % s, y = p / s;
        c.x0 = std::min(c.x0, x), c.x1 = std::max(c.x1, x);
        c.y0 = std::min(c.y0, y), c.y1 = std::max(c.y1, y);
        bool edge = false;
        for (int d : off4) edge = edge || (v[p + d] != kInk && v[p + d] != kInkSeen);
        c.boundary += edge;
        for (int d : off8) {
          if (v[p + d] == kInk) v[p + d] = kInkSeen, stack.push_back(p + d);
        }
      }
    } else {  // kBg: a hole; the pixel left of its first pixel is ink of the enclosing component
      const int id = static_cast<int>(holes.size());
      Hole h;
      h.parent = label[i - 1];
      h.first_span = spans.size();
      internal::SpanFill<true>(bm, i, kBg, kHoleSeen, [&](int row, int xl, int xr, int edges) {
        spans.push_back({row, xl, xr});
        h.area += xr - xl + 1;
        h.perimeter += edges;
      });
      h.spans = spans.size() - h.first_span;
      holes.push_back(h);
      comps[h.parent].holes.push_back(id);
    }
  };
  // Skip 8 bytes at a time while none is unvisited ink (1) or paper (0).
  const size_t words = npx / 8;
  for (size_t w = 0; w < words; ++w) {
    uint64_t x;
    std::memcpy(&x, v + 8 * w, 8);
    if (((x - 0x0202020202020202ULL) & ~x & 0x8080808080808080ULL) == 0) continue;
    for (size_t k = 8 * w; k < 8 * w + 8; ++k)
      if (v[k] <= kInk) visit(static_cast<int>(k));
  }
  for (size_t k = 8 * words; k < npx; ++k)
    if (v[k] <= kInk) visit(static_cast<int>(k));
  return out;
}

// Each component's kind (speck, drawn outline, filled silhouette, open line) from its size, line
// width, holes and roundness; a warning when specks were ignored.
// `width` x `height` is the picture's size.
void Classify(Components& parts, int width, int height, std::vector<std::string>& warnings) {
  const int64_t speck = std::max<int64_t>(16, int64_t(1e-4 * double(width) * height));
  int specks = 0;
  for (Component& c : parts.comps) {
    const double w = c.Width();
    for (int id : c.holes) {
      Hole& h = parts.holes[id];
      c.hole_area += h.area;
      const double thick = h.perimeter > 0 ? 2.0 * h.area / h.perimeter : 0.0;
      h.significant = h.area >= std::max(16.0, w * w) && thick >= std::max(2.0, 0.75 * w);
      if (h.significant) {
        ++c.significant;
        c.significant_area += h.area;
        c.largest_hole = std::max(c.largest_hole, h.area);
      }
    }
    if (c.area + c.hole_area < speck) {
      c.kind = Component::kSpeck;
      ++specks;
    } else if (c.significant > 0) {
      c.kind = w <= 0.35 * std::sqrt(double(c.largest_hole)) ? Component::kOutline
                                                             : Component::kSilhouette;
    } else {
      const double perim = double(c.boundary);
      const double roundness = perim * perim / (4.0 * M_PI * double(c.area));
      c.kind = (w >= 5.0 && roundness < 8.0) ? Component::kSilhouette : Component::kOpen;
    }
  }
  if (specks > 0) {
    warnings.push_back("ignored " + std::to_string(specks) + " speck(s) smaller than " +
                       std::to_string(speck) + " px");
  }
}

// One component's closed outline, as a dense chain in picture coordinates.
struct Extracted {
  std::vector<Vec2> chain;
  double enclosed = 0.0;
  double line_width = 0.0;
  bool silhouette = false;
  std::vector<std::string> notes;  // warnings
  std::vector<std::string> repairs;
  int comp = -1;
};

// The outline of one component: a drawn line is thinned, its extra lines removed (an open line's
// gap closed first) and the edge of what it encloses traced; a silhouette's edge is traced as it
// is. Keeps the time of each stage.
class Extractor {
 public:
  Extractor(const Components& parts, const ContourOptions& o) : parts_(parts), o_(o) {}

  // Drawn outline: thin, remove extra lines, fill what the line encloses, trace its edge.
  Result<Extracted> Line(int id) {
    const Component& c = parts_.comps[id];
    Extracted e;
    e.comp = id;
    auto t0 = Now();
    Bitmap b = Crop(c, false);
    internal::HilditchThin(b, o_.cancel);
    if (Status s = o_.cancel.Check("thinning"); !s) return s.error();
    auto t1 = Now();
    t_thin += Ms(t0, t1);
    Bitmap skeleton;
    if (c.kind == Component::kOpen) skeleton = b;  // for finding its ends
    internal::RemoveSpurs(b, o_.cancel);
    if (Status s = o_.cancel.Check("extra-line removal"); !s) return s.error();
    int64_t kept = b.Count();
    if (kept == 0 && skeleton.v.empty()) {
      return InvalidArgument("not closed: the line in " + Box(c) + " encloses nothing");
    }
    if (kept == 0) {
      if (Status s = CloseGap(c, skeleton, e); !s) return s.error();
      b = std::move(skeleton);
      internal::RemoveSpurs(b, o_.cancel);
      if (Status s = o_.cancel.Check("extra-line removal"); !s) return s.error();
      kept = b.Count();
      if (kept == 0)
        return InvalidArgument("not closed: the line in " + Box(c) + " encloses nothing");
    }
    auto t2 = Now();
    t_spur += Ms(t1, t2);
    e.line_width = double(c.area) / double(std::max<int64_t>(1, kept));
    // Moore tracing hugs the outside, so inner loops and lines are never entered.
    e.chain = ToChain(b, c);
    e.enclosed = std::abs(internal::SignedArea(e.chain));
    if (c.significant > 1) {
      e.notes.push_back("inner loops ignored: the outline in " + Box(c) + " encloses " +
                        std::to_string(c.significant) +
                        " separate regions; its outer edge is used");
    }
    t_trace += Ms(t2, Now());
    return e;
  }

  // Filled shape: its edge, holes filled.
  Extracted Silhouette(int id) {
    const Component& c = parts_.comps[id];
    Extracted e;
    e.comp = id;
    e.silhouette = true;
    auto t0 = Now();
    Bitmap b = Crop(c, true);
    e.line_width = 0.0;
    e.chain = ToChain(b, c);
    e.enclosed = std::abs(internal::SignedArea(e.chain));
    if (c.significant > 0) {
      e.notes.push_back("holes ignored: the filled shape in " + Box(c) + " has " +
                        std::to_string(c.significant) + " hole(s); its outer edge is used");
    }
    t_trace += Ms(t0, Now());
    return e;
  }

  double t_thin = 0, t_spur = 0, t_trace = 0;  // [ms]

 private:
  static std::chrono::steady_clock::time_point Now() { return std::chrono::steady_clock::now(); }
  static double Ms(std::chrono::steady_clock::time_point a,
                   std::chrono::steady_clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  }

  // Crop of one component: its ink, plus its slivers of paper (or all its holes).
  Bitmap Crop(const Component& c, bool fill_all_holes) const {
    const int s = parts_.stride;
    Bitmap b(c.x1 - c.x0 + 1, c.y1 - c.y0 + 1);
    const int cs = b.stride;
    auto to_crop = [&](int p) { return (p / s - c.y0 + 1) * cs + (p % s - c.x0 + 1); };
    for (size_t k = c.first_pixel; k < c.first_pixel + size_t(c.area); ++k)
      b.v[to_crop(parts_.ink[k])] = 1;
    for (int hid : c.holes) {
      const Hole& h = parts_.holes[hid];
      if (h.significant && !fill_all_holes) continue;
      for (size_t k = h.first_span; k < h.first_span + h.spans; ++k) {
        const Span& sp = parts_.spans[k];
        const int q = to_crop(sp.row + sp.xl);
        std::fill(b.v.begin() + q, b.v.begin() + q + (sp.xr - sp.xl + 1), 1);
      }
    }
    return b;
  }

  // The outer boundary of a crop of `c`, in picture coordinates (pixel centres).
  static std::vector<Vec2> ToChain(const Bitmap& region, const Component& c) {
    std::vector<Vec2> chain;
    for (auto [x, y] : internal::TraceOuterBoundary(region)) {
      chain.emplace_back(x + c.x0 - 1 + 0.5, y + c.y0 - 1 + 0.5);
    }
    return chain;
  }

  // Open line: its two far ends are the gap. Closes it in `skeleton` (the thinned line) when it is
  // within the closing limit, noting the repair in `e`; otherwise the refusal.
  Status CloseGap(const Component& c, Bitmap& skeleton, Extracted& e) const {
    std::vector<int> dist(skeleton.v.size());
    int start = 0;
    while (!skeleton.v[start]) ++start;
    const auto [a, da] = Farthest(skeleton, start, dist);
    const auto [bb, len] = Farthest(skeleton, a, dist);
    const int ax = a % skeleton.stride - 1, ay = a / skeleton.stride - 1;
    const int bx = bb % skeleton.stride - 1, by = bb / skeleton.stride - 1;
    const Vec2 pa(ax + c.x0 - 1 + 0.5, ay + c.y0 - 1 + 0.5);
    const Vec2 pb(bx + c.x0 - 1 + 0.5, by + c.y0 - 1 + 0.5);
    const double gap = (pa - pb).norm();
    const double limit = o_.max_gap_fraction * (len + gap);
    if (gap > limit) {
      return InvalidArgument("not closed: gap of " + Num(gap, 0) + " px between " + Pt(pa) +
                             " and " + Pt(pb) + " (closing limit " + Num(limit, 0) +
                             " px = " + Num(100 * o_.max_gap_fraction, 0) + " % of the perimeter)");
    }
    DrawLine(skeleton, ax, ay, bx, by);
    e.repairs.push_back("closed a gap of " + Num(gap) + " px between " + Pt(pa) + " and " + Pt(pb));
    return Status::Ok();
  }

  const Components& parts_;
  const ContourOptions& o_;
};

// The candidates (every component but the specks), largest first (ink and holes).
std::vector<int> Candidates(const Components& parts) {
  const std::vector<Component>& comps = parts.comps;
  std::vector<int> order;
  for (size_t k = 0; k < comps.size(); ++k)
    if (comps[k].kind != Component::kSpeck) order.push_back(static_cast<int>(k));
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return comps[a].area + comps[a].hole_area > comps[b].area + comps[b].hole_area;
  });
  return order;
}

// The outline that encloses the most, of the candidates in `order`: closed candidates by enclosed
// area; the largest open line competes if it could be bigger. Without one, the open line's
// refusal, if any.
struct Selection {
  std::optional<Extracted> best;
  std::optional<Error> open_error;
};
Selection SelectLargest(const Components& parts, const std::vector<int>& order, Extractor& ex) {
  Selection sel;
  std::optional<Extracted>& best = sel.best;
  int open_tried = -1;
  for (int id : order) {
    const Component& c = parts.comps[id];
    const double bound = double(c.x1 - c.x0 + 1) * (c.y1 - c.y0 + 1);
    if (best && bound <= best->enclosed) break;
    if (c.kind == Component::kOpen) {
      if (open_tried >= 0) continue;
      open_tried = id;
      auto e = ex.Line(id);
      if (!e.ok()) {
        if (!sel.open_error) sel.open_error = e.error();
        continue;
      }
      if (!best || e->enclosed > best->enclosed) best = std::move(*e);
    } else if (c.kind == Component::kOutline) {
      auto e = ex.Line(id);
      if (!e.ok()) continue;
      if (!best || e->enclosed > best->enclosed) best = std::move(*e);
    } else {
      auto e = ex.Silhouette(id);
      if (!best || e.enclosed > best->enclosed) best = std::move(e);
    }
  }
  return sel;
}

// A warning for each candidate other than the one used.
void WarnIgnored(const Components& parts, const std::vector<int>& order, int used,
                 std::vector<std::string>& warnings) {
  for (int id : order) {
    if (id == used) continue;
    const Component& c = parts.comps[id];
    const char* what = c.kind == Component::kOpen      ? "an open line"
                       : c.kind == Component::kOutline ? "a closed outline"
                                                       : "a filled shape";
    warnings.push_back(std::string("several shapes: ignored ") + what + " in " + Box(c) +
                       "; the largest is used");
  }
}

}  // namespace

// decode, binarize, components (and their kinds), then per candidate thin, spurs (extra-line
// removal) and trace, the largest kept (select), then vectorize: each stage's time in r.timings.
Result<std::pair<int, int>> DecodePictureSize(std::span<const uint8_t> bytes,
                                              const ContourOptions& o) {
  if (Status s = CheckOptions(o); !s) return s.error();
  ContourResult r;
  Result<internal::GrayImage> img = Decode(bytes, o, r);
  if (!img.ok()) return img.error();
  return std::pair<int, int>(r.width, r.height);
}

Result<ContourResult> ContourFromImage(std::span<const uint8_t> bytes, const ContourOptions& o) {
  if (Status s = CheckOptions(o); !s) return s.error();
  ContourResult r;
  Stopwatch sw;
  Result<internal::GrayImage> img = Decode(bytes, o, r);
  if (!img.ok()) return img.error();
  sw.Lap("decode", r);
  if (Status s = o.cancel.Check("decoding"); !s) return s.error();

  Bitmap bm = internal::Binarize(*img, o, &r.binarization, &r.warnings);
  img = InvalidArgument("");  // release the grey picture
  sw.Lap("binarize", r);
  if (Status s = o.cancel.Check("binarization"); !s) return s.error();

  Components parts = FindComponents(bm);
  sw.Lap("components", r);
  if (Status s = o.cancel.Check("component labelling"); !s) return s.error();
  Classify(parts, r.width, r.height, r.warnings);

  const std::vector<int> order = Candidates(parts);
  if (order.empty()) {
    return InvalidArgument("nothing drawn: no ink found in the " + std::to_string(r.width) + " x " +
                           std::to_string(r.height) + " picture (" + r.binarization + ")");
  }
  Extractor ex(parts, o);
  Selection sel = SelectLargest(parts, order, ex);
  if (Status s = o.cancel.Check("outline extraction"); !s) return s.error();
  r.timings.push_back({"thin", ex.t_thin});
  r.timings.push_back({"spurs", ex.t_spur});
  r.timings.push_back({"trace", ex.t_trace});
  sw.Lap("select", r);
  r.timings.back().ms = std::max(0.0, r.timings.back().ms - ex.t_thin - ex.t_spur - ex.t_trace);
  if (!sel.best) {
    if (sel.open_error) return *sel.open_error;
    return InvalidArgument("nothing closed drawn: no outline or filled shape found");
  }
  Extracted& best = *sel.best;
  WarnIgnored(parts, order, best.comp, r.warnings);
  for (auto& n : best.notes) r.warnings.push_back(std::move(n));
  for (auto& n : best.repairs) r.repairs.push_back(std::move(n));
  r.filled_silhouette = best.silhouette;
  r.line_width_px = best.line_width;
  if (Status st = Finish(std::move(best.chain), o, r); !st) return st.error();
  sw.Lap("vectorize", r);
  return r;
}

Result<ContourResult> ContourFromSketchBytes(std::span<const uint8_t> bytes,
                                             const ContourOptions& o) {
  if (internal::LooksLikePng(bytes) || internal::LooksLikeJpeg(bytes)) {
    return ContourFromImage(bytes, o);
  }
  size_t k = 0;
  while (k < bytes.size() &&
         (bytes[k] == ' ' || bytes[k] == '\n' || bytes[k] == '\r' || bytes[k] == '\t')) {
    ++k;
  }
  if (k < bytes.size() && bytes[k] == '{') {
    return ContourFromStrokesJson(
        std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), o);
  }
  if (bytes.empty()) return InvalidArgument("nothing drawn: the sketch is empty");
  return InvalidArgument(
      "unknown sketch format: expected stroke JSON (starting with '{'), PNG or JPEG");
}

double SymmetricHausdorff(const std::vector<Vec2>& a, const std::vector<Vec2>& b,
                          double sample_px) {
  auto directed = [sample_px](const std::vector<Vec2>& p, const std::vector<Vec2>& q) {
    double worst = 0.0;
    for (size_t i = 0; i < p.size(); ++i) {
      const Vec2& u = p[i];
      const Vec2& w = p[(i + 1) % p.size()];
      const int n = std::max(1, static_cast<int>(std::ceil((w - u).norm() / sample_px)));
      for (int k = 0; k < n; ++k) {
        worst = std::max(worst, internal::PointPolygonDistance(u + (w - u) * (double(k) / n), q));
      }
    }
    return worst;
  };
  if (a.empty() || b.empty()) return INFINITY;
  return std::max(directed(a, b), directed(b, a));
}

}  // namespace rheo::sketch
