#include "sketch/strokes.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <optional>

#include "sketch/format.h"
#include "sketch/polyline.h"

namespace rheo::sketch::internal {
namespace {

using json = nlohmann::json;

// Streaming handler: builds the StrokeSet directly, refusing anything off the expected shape.
class StrokeSax : public nlohmann::json_sax<json> {
 public:
  StrokeSax(StrokeSet* out, int64_t max_points) : out_(out), max_points_(max_points) {}

  std::optional<Error> error;

  bool null() override { return Scalar("null"); }
  bool boolean(bool) override { return Scalar("a boolean"); }
  bool number_integer(number_integer_t v) override { return Number(static_cast<double>(v)); }
  bool number_unsigned(number_unsigned_t v) override { return Number(static_cast<double>(v)); }
  bool number_float(number_float_t v, const string_t&) override { return Number(v); }
  bool string(string_t&) override { return Scalar("a string"); }
  bool binary(binary_t&) override { return Scalar("binary data"); }

  bool start_object(std::size_t) override {
    if (skip_ > 0) return ++skip_, true;
    if (level_ == Level::kTop) return level_ = Level::kRoot, true;
    if (level_ == Level::kRoot) return ++skip_, true;  // value of an unknown key
    return Fail(Where() + ": expected an array, found an object");
  }
  bool end_object() override {
    if (skip_ > 0) return --skip_, true;
    level_ = Level::kDone;
    return true;
  }
  bool key(string_t& k) override {
    if (skip_ > 0) return true;
    key_ = k;
    return true;
  }
  bool start_array(std::size_t) override {
    if (skip_ > 0) return ++skip_, true;
    switch (level_) {
      case Level::kTop: return Fail("the sketch must be a JSON object, found an array");
      case Level::kRoot:
        if (key_ == "strokes") {
          if (seen_strokes_) return Fail("\"strokes\" appears twice");
          seen_strokes_ = true;
          return level_ = Level::kStrokes, true;
        }
        if (key_ == "width" || key_ == "height") return Fail("\"" + key_ + "\" must be a number");
        return ++skip_, true;
      case Level::kStrokes: out_->strokes.emplace_back(); return level_ = Level::kStroke, true;
      case Level::kStroke: coords_ = 0; return level_ = Level::kPoint, true;
      case Level::kPoint: return Fail(Where() + ": expected a number, found an array");
      case Level::kDone: return Fail("data after the end of the sketch");
    }
    return false;
  }
  bool end_array() override {
    if (skip_ > 0) return --skip_, true;
    switch (level_) {
      case Level::kStrokes: return level_ = Level::kRoot, true;
      case Level::kStroke: return level_ = Level::kStrokes, true;
      case Level::kPoint:
        if (coords_ != 2) return Fail(Where() + ": a point must be [x, y] with two numbers");
        level_ = Level::kStroke;
        return true;
      default: return Fail("unexpected end of array");
    }
  }
  bool parse_error(std::size_t position, const std::string& last_token,
                   const nlohmann::detail::exception&) override {
    return Fail("not valid JSON: syntax error at byte " + std::to_string(position) + " near '" +
                last_token.substr(0, 20) + "'");
  }

  bool seen_width = false, seen_height = false, seen_strokes_ = false;

 private:
  enum class Level { kTop, kRoot, kStrokes, kStroke, kPoint, kDone };

  std::string Where() const {
    const size_t k = out_->strokes.empty() ? 0 : out_->strokes.size() - 1;
    std::string w = "strokes[" + std::to_string(k) + "]";
    if (level_ == Level::kPoint || level_ == Level::kStroke) {
      const size_t n = out_->strokes.back().size();
      w += "[" + std::to_string(level_ == Level::kPoint && coords_ > 0 ? n - 1 : n) + "]";
    }
    return w;
  }
  bool Fail(std::string m) {
    if (!error) error = InvalidArgument(std::move(m));
    return false;
  }
  bool Scalar(const char* what) {
    if (skip_ > 0 ||
        (level_ == Level::kRoot && key_ != "width" && key_ != "height" && key_ != "strokes")) {
      return true;
    }
    if (level_ == Level::kRoot) return Fail("\"" + key_ + "\" must be a number, found " + what);
    return Fail(Where() + ": expected a number, found " + std::string(what));
  }
  bool Number(double v) {
    if (skip_ > 0) return true;
    if (level_ == Level::kRoot) {
      if (key_ == "width" || key_ == "height") {
        if (!(v >= 1 && v <= 1e6) || v != std::floor(v)) {
          return Fail("\"" + key_ + "\" must be a whole number of pixels in 1..1000000, found " +
                      Num(v, 2));
        }
        (key_ == "width" ? out_->width : out_->height) = static_cast<int>(v);
        (key_ == "width" ? seen_width : seen_height) = true;
        return true;
      }
      if (key_ == "strokes") return Fail("\"strokes\" must be an array of strokes");
      return true;
    }
    if (level_ != Level::kPoint) return Fail(Where() + ": expected [x, y], found a number");
    if (!std::isfinite(v) || std::abs(v) > 1e6) {
      return Fail(Where() + ": coordinate " + Num(v, 2) + " is outside -1e6..1e6");
    }
    if (coords_ >= 2) return Fail(Where() + ": a point must be [x, y] with two numbers");
    if (coords_ == 0) {
      if (++points_ > max_points_) {
        error = ResourceExhausted("the stroke list has more than " + std::to_string(max_points_) +
                                  " points (limit max_stroke_points)");
        return false;
      }
      out_->strokes.back().emplace_back(v, 0.0);
    } else {
      out_->strokes.back().back().y() = v;
    }
    ++coords_;
    return true;
  }

  StrokeSet* out_;
  int64_t max_points_;
  int64_t points_ = 0;
  Level level_ = Level::kTop;
  int skip_ = 0;  // nesting depth inside a value that is ignored
  int coords_ = 0;
  std::string key_;
};

// A place on a polyline: edge index i (from p[i] to p[i+1]) and fraction t along it.
struct Cut {
  int i = 0;
  double t = 0.0;
};

Vec2 At(const std::vector<Vec2>& p, Cut c) {
  if (c.i + 1 >= static_cast<int>(p.size())) return p.back();
  return p[c.i] + c.t * (p[c.i + 1] - p[c.i]);
}

// First index of the trailing part of p with arc length <= w.
int TailStart(const std::vector<Vec2>& p, double w) {
  double l = 0.0;
  int i = static_cast<int>(p.size()) - 1;
  while (i > 0 && l + (p[i] - p[i - 1]).norm() <= w) l += (p[i] - p[i - 1]).norm(), --i;
  return std::max(0, i - 1);
}
// Last index of the leading part of p with arc length <= w.
int HeadEnd(const std::vector<Vec2>& p, double w) {
  double l = 0.0;
  int i = 0;
  const int n = static_cast<int>(p.size());
  while (i + 1 < n && l + (p[i + 1] - p[i]).norm() <= w) l += (p[i + 1] - p[i]).norm(), ++i;
  return std::min(n - 1, i + 1);
}

// How to join a's end to b's start: keep a up to cut_a, bridge `gap`, continue b from cut_b.
struct Join {
  double gap = INFINITY;
  Cut cut_a;  // on a
  Cut cut_b;  // on b
  bool crossed = false;
};

Cut Nearest(const std::vector<Vec2>& p, int first, int last, const Vec2& q, double* dist) {
  Cut best{last, 0.0};
  double bd = INFINITY;
  for (int i = first; i < last; ++i) {
    const Vec2 d = p[i + 1] - p[i];
    const double l2 = d.squaredNorm();
    const double t = l2 > 0 ? std::clamp((q - p[i]).dot(d) / l2, 0.0, 1.0) : 0.0;
    const double dd = (q - (p[i] + t * d)).norm();
    if (dd < bd) bd = dd, best = {i, t};
  }
  *dist = bd;
  return best;
}

// Best way to continue a (at its end) with b (at its start), looking at windows of length w.
Join BestJoin(const std::vector<Vec2>& a, const std::vector<Vec2>& b, double w) {
  const int na = static_cast<int>(a.size());
  Join j;
  j.gap = (a.back() - b.front()).norm();
  j.cut_a = {na - 1, 0.0};
  j.cut_b = {0, 0.0};
  const int a0 = TailStart(a, w);
  const int b1 = HeadEnd(b, w);
  // Crossing of the two ends: an overshoot or overdraw; cut both there (gap 0). Keep the most.
  double best_lost = INFINITY;
  Eigen::AlignedBox2d bbox;
  for (int k = 0; k <= b1; ++k) bbox.extend(b[k]);
  for (int i = na - 2; i >= a0; --i) {
    Eigen::AlignedBox2d seg(a[i].cwiseMin(a[i + 1]), a[i].cwiseMax(a[i + 1]));
    if (!seg.intersects(bbox)) continue;
    for (int k = 0; k < b1; ++k) {
      const Vec2 &p = a[i], &q = a[i + 1], &r = b[k], &s = b[k + 1];
      if (std::max(r.x(), s.x()) < std::min(p.x(), q.x()) ||
          std::min(r.x(), s.x()) > std::max(p.x(), q.x()) ||
          std::max(r.y(), s.y()) < std::min(p.y(), q.y()) ||
          std::min(r.y(), s.y()) > std::max(p.y(), q.y())) {
        continue;
      }
      if (auto hit = IntersectSegments(p, q, r, s)) {
        const double lost = (na - 1 - i - hit->t_ab) + (k + hit->t_cd);  // in points, roughly
        if (lost < best_lost) {
          best_lost = lost;
          j = {0.0, {i, hit->t_ab}, {k, hit->t_cd}, true};
        }
      }
    }
  }
  if (j.crossed) return j;
  double da, db;
  const Cut ca = Nearest(a, a0, na - 1, b.front(), &da);
  const Cut cb = Nearest(b, 0, b1, a.back(), &db);
  if (da < j.gap && da <= db) j = {da, ca, {0, 0.0}, false};
  if (db < j.gap && db < da) j = {db, {na - 1, 0.0}, cb, false};
  return j;
}

// a[0..cut] followed by b[cut..end].
std::vector<Vec2> Splice(const std::vector<Vec2>& a, Cut ca, const std::vector<Vec2>& b, Cut cb) {
  std::vector<Vec2> out(a.begin(), a.begin() + std::min<int>(ca.i + 1, a.size()));
  if (ca.i + 1 < static_cast<int>(a.size()) && ca.t > 0.0) out.push_back(At(a, ca));
  const Vec2 start_b = At(b, cb);
  if (out.empty() || (out.back() - start_b).norm() > 1e-9) out.push_back(start_b);
  for (size_t k = cb.i + 1; k < b.size(); ++k) out.push_back(b[k]);
  return out;
}

void Clean(std::vector<Vec2>& p) {
  std::vector<Vec2> out;
  out.reserve(p.size());
  for (const Vec2& q : p)
    if (out.empty() || (q - out.back()).norm() > 1e-6) out.push_back(q);
  p = std::move(out);
}

struct Chain {
  std::vector<Vec2> pts;
  std::vector<int> strokes;  // stroke indices joined, in order
  std::vector<std::string> repairs;
};

}  // namespace

Result<StrokeSet> ParseStrokesJson(std::string_view text, const ContourOptions& options) {
  if (static_cast<int64_t>(text.size()) > options.max_input_bytes) {
    return ResourceExhausted("the stroke JSON is " + std::to_string(text.size()) +
                             " bytes, over the limit of " +
                             std::to_string(options.max_input_bytes) + " (max_input_bytes)");
  }
  StrokeSet set;
  StrokeSax sax(&set, options.max_stroke_points);
  bool ok = false;
  try {
    ok = json::sax_parse(text.begin(), text.end(), &sax);
  } catch (const std::exception& e) {
    return InvalidArgument(std::string("not valid JSON: ") + e.what());
  }
  if (sax.error) return *sax.error;
  if (!ok) return InvalidArgument("not valid JSON");
  if (!sax.seen_strokes_) return InvalidArgument("the sketch has no \"strokes\" array");
  if (!sax.seen_width || !sax.seen_height) {
    return InvalidArgument("the sketch needs \"width\" and \"height\" (canvas size in pixels)");
  }
  return set;
}

Result<MergedOutline> MergeStrokes(const StrokeSet& set, const ContourOptions& options) {
  MergedOutline out;
  std::vector<std::vector<Vec2>> strokes;
  std::vector<int> ids;
  for (size_t s = 0; s < set.strokes.size(); ++s) {
    std::vector<Vec2> p = set.strokes[s];
    Clean(p);
    if (p.size() < 2) {
      if (!p.empty())
        out.warnings.push_back("ignored a dot at " + Pt(p[0]) + " (stroke " + std::to_string(s) +
                               ")");
      continue;
    }
    strokes.push_back(std::move(p));
    ids.push_back(static_cast<int>(s));
  }
  if (strokes.empty())
    return InvalidArgument(
        "nothing drawn: the sketch has no stroke with two or more distinct points");

  std::vector<double> len(strokes.size());
  for (size_t s = 0; s < strokes.size(); ++s) len[s] = OpenLength(strokes[s]);
  std::vector<char> used(strokes.size(), 0);
  std::vector<Chain> chains;
  const double frac = options.max_gap_fraction;
  for (;;) {
    int seed = -1;
    for (size_t s = 0; s < strokes.size(); ++s)
      if (!used[s] && (seed < 0 || len[s] > len[seed])) seed = static_cast<int>(s);
    if (seed < 0) break;
    used[seed] = 1;
    Chain chain{strokes[seed], {ids[seed]}, {}};
    for (;;) {
      const double lc = OpenLength(chain.pts);
      int best = -1;
      bool best_head = false, best_rev = false;
      Join best_join;
      for (size_t s = 0; s < strokes.size(); ++s) {
        if (used[s]) continue;
        const double w = std::min({0.35 * lc, 0.35 * len[s], 0.05 * (lc + len[s]) + 15.0});
        const double limit = frac * (lc + len[s]);
        for (int head = 0; head < 2; ++head) {
          const Vec2 end = head ? chain.pts.front() : chain.pts.back();
          for (int rev = 0; rev < 2; ++rev) {
            const Vec2 sb = rev ? strokes[s].back() : strokes[s].front();
            if ((end - sb).norm() > limit + 2.0 * w) continue;  // cannot be within reach
            std::vector<Vec2> a = chain.pts, b = strokes[s];
            if (head) std::reverse(a.begin(), a.end());
            if (rev) std::reverse(b.begin(), b.end());
            Join j = BestJoin(a, b, w);
            if (j.gap <= limit && j.gap < best_join.gap) {
              best_join = j, best = static_cast<int>(s), best_head = head, best_rev = rev;
            }
          }
        }
      }
      if (best < 0) break;
      std::vector<Vec2> a = chain.pts, b = strokes[best];
      if (best_head) std::reverse(a.begin(), a.end());
      if (best_rev) std::reverse(b.begin(), b.end());
      const Vec2 pa = At(a, best_join.cut_a), pb = At(b, best_join.cut_b);
      chain.pts = Splice(a, best_join.cut_a, b, best_join.cut_b);
      Clean(chain.pts);
      const std::string names =
          "strokes " + std::to_string(chain.strokes.back()) + " and " + std::to_string(ids[best]);
      if (best_join.crossed) {
        chain.repairs.push_back("joined " + names + " where they cross at " + Pt(pa) +
                                ", overdrawn ends trimmed");
      } else if (best_join.gap > 0.5) {
        chain.repairs.push_back("joined " + names + " across a gap of " + Num(best_join.gap) +
                                " px between " + Pt(pa) + " and " + Pt(pb));
      }
      chain.strokes.push_back(ids[best]);
      used[best] = 1;
    }
    chains.push_back(std::move(chain));
  }

  // Close each chain onto itself; the closed ones compete by area.
  struct Candidate {
    std::vector<Vec2> closed;
    double area = 0.0;
    std::string repair;
    size_t chain = 0;
  };
  std::vector<Candidate> closed;
  struct Open {
    double gap;
    Vec2 a, b;
    double limit;
    double length;
    size_t chain;
  };
  std::vector<Open> open;
  for (size_t c = 0; c < chains.size(); ++c) {
    const auto& p = chains[c].pts;
    const double l = OpenLength(p);
    const double limit = frac * l;
    const double w = std::min(0.35 * l, 0.05 * l + 15.0);
    std::vector<Vec2> head(p.begin(), p.begin() + HeadEnd(p, w) + 1);
    std::vector<Vec2> tail(p.begin() + TailStart(p, w), p.end());
    const int tail_off = TailStart(p, w);
    const Join j = p.size() >= 3 ? BestJoin(tail, head, w) : Join{};
    const Vec2 pa = p.size() >= 3 ? At(tail, j.cut_a) : p.back();
    const Vec2 pb = p.size() >= 3 ? At(head, j.cut_b) : p.front();
    if (p.size() < 3 || j.gap > limit) {
      open.push_back({(p.back() - p.front()).norm(), p.back(), p.front(), limit, l, c});
      if (p.size() >= 3 && j.gap < open.back().gap) {
        open.back().gap = j.gap, open.back().a = pa, open.back().b = pb;
      }
      continue;
    }
    // The loop runs from cut_b on the head to cut_a on the tail.
    std::vector<Vec2> loop;
    loop.push_back(pb);
    const int a_end = tail_off + j.cut_a.i;  // last whole point kept
    for (int k = j.cut_b.i + 1; k <= a_end; ++k) loop.push_back(p[k]);
    loop.push_back(pa);
    Clean(loop);
    if ((loop.front() - loop.back()).norm() < 1e-6) loop.pop_back();
    if (loop.size() < 3) continue;
    Candidate cand{std::move(loop), 0.0, "", c};
    cand.area = std::abs(SignedArea(cand.closed));
    if (j.crossed) {
      cand.repair =
          "closed the outline where its ends cross at " + Pt(pa) + ", overdrawn ends trimmed";
    } else if (j.gap > 0.5) {
      cand.repair = "closed a gap of " + Num(j.gap) + " px between " + Pt(pa) + " and " + Pt(pb);
    }
    closed.push_back(std::move(cand));
  }
  if (closed.empty() && open.empty())
    return InvalidArgument(
        "no closed outline: the strokes enclose no area (fewer than 3 distinct "
        "points after merging)");
  if (closed.empty()) {
    const auto it = std::max_element(
        open.begin(), open.end(), [](const Open& x, const Open& y) { return x.length < y.length; });
    return InvalidArgument("not closed: gap of " + Num(it->gap, 0) + " px between " + Pt(it->a) +
                           " and " + Pt(it->b) + " (closing limit " + Num(it->limit, 0) +
                           " px = " + Num(100 * frac, 0) + " % of the perimeter)");
  }
  size_t pick = 0;
  for (size_t k = 1; k < closed.size(); ++k)
    if (closed[k].area > closed[pick].area) pick = k;
  for (size_t k = 0; k < closed.size(); ++k) {
    if (k == pick) continue;
    Eigen::AlignedBox2d box;
    for (const Vec2& q : closed[k].closed) box.extend(q);
    out.warnings.push_back("several shapes: ignored a closed outline of area " +
                           Num(closed[k].area, 0) + " px^2 in " + Pt(box.min()) + "-" +
                           Pt(box.max()) + "; the largest is used");
  }
  for (const Open& o : open) {
    out.warnings.push_back("ignored an open stroke from " + Pt(o.b) + " to " + Pt(o.a) +
                           " (gap of " + Num(o.gap, 0) + " px, over the closing limit)");
  }
  out.repairs = chains[closed[pick].chain].repairs;
  if (!closed[pick].repair.empty()) out.repairs.push_back(closed[pick].repair);
  out.closed = std::move(closed[pick].closed);
  return out;
}

}  // namespace rheo::sketch::internal
