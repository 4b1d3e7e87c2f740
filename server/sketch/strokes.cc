#include "sketch/strokes.h"

#include <simdjson.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <optional>

#include "sketch/format.h"
#include "sketch/polyline.h"

namespace rheo::sketch::internal {
namespace {

// Names a JSON value's type for messages.
const char* TypeName(simdjson::ondemand::json_type t) {
  using T = simdjson::ondemand::json_type;
  switch (t) {
    case T::array: return "an array";
    case T::object: return "an object";
    case T::number: return "a number";
    case T::string: return "a string";
    case T::boolean: return "a boolean";
    case T::null: return "null";
  }
  return "a value";
}

// Locates a syntax error for the message: a second, streaming pass that stores nothing. The
// fast reader below knows that the text is broken but not where; this runs only then.
class SyntaxLocator : public nlohmann::json_sax<nlohmann::json> {
 public:
  std::string message;
  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override { return true; }
  bool end_object() override { return true; }
  bool key(string_t&) override { return true; }
  bool start_array(std::size_t) override { return true; }
  bool end_array() override { return true; }
  bool parse_error(std::size_t position, const std::string&,
                   const nlohmann::detail::exception& e) override {
    // e.what() reads "[json.exception.parse_error.101] parse error at line 1, column 9: ...".
    std::string what = e.what();
    const size_t at = what.find("parse error at ");
    message = "syntax error at byte " + std::to_string(position) + " (" +
              (at == std::string::npos ? what : what.substr(at + 15)) + ")";
    return false;
  }
};

Error SyntaxError(simdjson::error_code e, std::string_view text) {
  SyntaxLocator where;
  nlohmann::json::sax_parse(text.begin(), text.end(), &where, nlohmann::json::input_format_t::json,
                            /*strict=*/true);
  if (!where.message.empty()) return InvalidArgument("not valid JSON: " + where.message);
  return InvalidArgument(std::string("not valid JSON: ") + simdjson::error_message(e));
}

// Reads {"width": W, "height": H, "strokes": [[[x, y], ...], ...]} in one forward pass over the
// text (simdjson on-demand: numbers parsed in place, no document tree). Unknown keys are skipped.
class StrokeReader {
 public:
  StrokeReader(StrokeSet* out, int64_t max_points) : out_(out), max_points_(max_points) {}

  Status Read(std::string_view text) {
    text_ = text;
    simdjson::padded_string padded(text.data(), text.size());
    simdjson::ondemand::parser parser;
    simdjson::ondemand::document doc;
    if (auto e = parser.iterate(padded).get(doc)) return SyntaxError(e, text_);
    simdjson::ondemand::json_type type;
    if (auto e = doc.type().get(type)) return SyntaxError(e, text_);
    if (type != simdjson::ondemand::json_type::object)
      return InvalidArgument(std::string("the sketch must be a JSON object, found ") +
                             TypeName(type));
    simdjson::ondemand::object root;
    if (auto e = doc.get_object().get(root)) return SyntaxError(e, text_);
    for (auto field : root) {
      std::string_view key;
      if (auto e = field.unescaped_key().get(key)) return SyntaxError(e, text_);
      simdjson::ondemand::value v;
      if (auto e = field.value().get(v)) return SyntaxError(e, text_);
      Status s = Status::Ok();
      if (key == "width" || key == "height") {
        s = ReadSize(v, key);
      } else if (key == "strokes") {
        if (seen_strokes) return InvalidArgument("\"strokes\" appears twice");
        seen_strokes = true;
        s = ReadStrokes(v);
      } else if (auto e = Skip(v, 1)) {
        return SyntaxError(e, text_);
      }
      if (!s.ok()) return s;
    }
    // At the end of the text the parser has no location left; one still there is trailing data.
    const char* rest = nullptr;
    if (doc.current_location().get(rest) == simdjson::SUCCESS)
      return SyntaxError(simdjson::TRAILING_CONTENT, text_);
    return Status::Ok();
  }

  bool seen_width = false, seen_height = false, seen_strokes = false;

 private:
  // A type error, named at `where`; anything else is a syntax error.
  Status Expected(simdjson::ondemand::value& v, const std::string& where, const char* what) {
    simdjson::ondemand::json_type t;
    if (auto e = v.type().get(t)) return SyntaxError(e, text_);
    return InvalidArgument(where + ": expected " + what + ", found " + TypeName(t));
  }

  // Walks a value that is not used, so that it is validated all the same (the reader otherwise
  // checks only what it reads).
  static simdjson::error_code Skip(simdjson::ondemand::value v, int depth) {
    using T = simdjson::ondemand::json_type;
    if (depth > kMaxDepth) return simdjson::DEPTH_ERROR;
    T t;
    if (auto e = v.type().get(t)) return e;
    switch (t) {
      case T::array: {
        simdjson::ondemand::array a;
        if (auto e = v.get_array().get(a)) return e;
        for (auto item : a) {
          simdjson::ondemand::value c;
          if (auto e = item.get(c)) return e;
          if (auto e = Skip(c, depth + 1)) return e;
        }
        return simdjson::SUCCESS;
      }
      case T::object: {
        simdjson::ondemand::object o;
        if (auto e = v.get_object().get(o)) return e;
        for (auto field : o) {
          std::string_view k;
          if (auto e = field.unescaped_key().get(k)) return e;
          simdjson::ondemand::value c;
          if (auto e = field.value().get(c)) return e;
          if (auto e = Skip(c, depth + 1)) return e;
        }
        return simdjson::SUCCESS;
      }
      case T::number: return v.get_double().error();
      case T::string: return v.get_string().error();
      case T::boolean: return v.get_bool().error();
      case T::null: {
        bool is_null = false;
        if (auto e = v.is_null().get(is_null)) return e;
        return is_null ? simdjson::SUCCESS : simdjson::N_ATOM_ERROR;
      }
    }
    return simdjson::INCORRECT_TYPE;
  }
  static constexpr int kMaxDepth = 256;

  Status ReadSize(simdjson::ondemand::value& v, std::string_view key) {
    double d = 0;
    if (v.get_double().get(d)) {
      simdjson::ondemand::json_type t;
      if (auto e = v.type().get(t)) return SyntaxError(e, text_);
      if (t == simdjson::ondemand::json_type::number)
        return SyntaxError(simdjson::NUMBER_ERROR, text_);
      return InvalidArgument("\"" + std::string(key) + "\" must be a number, found " + TypeName(t));
    }
    if (!(d >= 1 && d <= 1e6) || d != std::floor(d))
      return InvalidArgument("\"" + std::string(key) +
                             "\" must be a whole number of pixels in 1..1000000, found " +
                             Num(d, 2));
    (key == "width" ? out_->width : out_->height) = static_cast<int>(d);
    (key == "width" ? seen_width : seen_height) = true;
    return Status::Ok();
  }

  Status ReadStrokes(simdjson::ondemand::value& v) {
    simdjson::ondemand::array strokes;
    if (v.get_array().get(strokes)) {
      simdjson::ondemand::json_type t;
      if (auto e = v.type().get(t)) return SyntaxError(e, text_);
      return InvalidArgument(std::string("\"strokes\" must be an array of strokes, found ") +
                             TypeName(t));
    }
    for (auto stroke_r : strokes) {
      simdjson::ondemand::value stroke_v;
      if (auto e = stroke_r.get(stroke_v)) return SyntaxError(e, text_);
      const std::string where = "strokes[" + std::to_string(out_->strokes.size()) + "]";
      out_->strokes.emplace_back();
      simdjson::ondemand::array stroke;
      if (stroke_v.get_array().get(stroke))
        return Expected(stroke_v, where, "an array of [x, y] points");
      for (auto point_r : stroke) {
        simdjson::ondemand::value point_v;
        if (auto e = point_r.get(point_v)) return SyntaxError(e, text_);
        if (++points_ > max_points_)
          return ResourceExhausted("the stroke list has more than " + std::to_string(max_points_) +
                                   " points (limit max_stroke_points)");
        auto& pts = out_->strokes.back();
        auto here = [&] { return where + "[" + std::to_string(pts.size()) + "]"; };
        simdjson::ondemand::array point;
        if (point_v.get_array().get(point)) return Expected(point_v, here(), "[x, y]");
        double xy[2] = {0, 0};
        int n = 0;
        for (auto coord_r : point) {
          simdjson::ondemand::value c;
          if (auto e = coord_r.get(c)) return SyntaxError(e, text_);
          if (n >= 2) return InvalidArgument(here() + ": a point must be [x, y] with two numbers");
          double d = 0;
          if (c.get_double().get(d)) {
            simdjson::ondemand::json_type t;
            if (auto e = c.type().get(t)) return SyntaxError(e, text_);
            if (t == simdjson::ondemand::json_type::number) {
              return InvalidArgument(here() + ": a coordinate is outside -1e6..1e6");
            }
            return InvalidArgument(here() + ": expected a number, found " + TypeName(t));
          }
          if (!std::isfinite(d) || std::abs(d) > 1e6)
            return InvalidArgument(here() + ": coordinate " + Num(d, 2) + " is outside -1e6..1e6");
          xy[n++] = d;
        }
        if (n != 2) return InvalidArgument(here() + ": a point must be [x, y] with two numbers");
        pts.emplace_back(xy[0], xy[1]);
      }
    }
    return Status::Ok();
  }

  StrokeSet* out_;
  int64_t max_points_;
  int64_t points_ = 0;
  std::string_view text_;  // the whole input, for locating syntax errors
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
  StrokeReader reader(&set, options.max_stroke_points);
  if (Status s = reader.Read(text); !s.ok()) return s.error();
  if (!reader.seen_strokes) return InvalidArgument("the sketch has no \"strokes\" array");
  if (!reader.seen_width || !reader.seen_height) {
    return InvalidArgument("the sketch needs \"width\" and \"height\" (canvas size in pixels)");
  }
  // A point far off the canvas is a glitch of the input device or the file, not a drawing.
  for (size_t k = 0; k < set.strokes.size(); ++k) {
    for (size_t i = 0; i < set.strokes[k].size(); ++i) {
      const Vec2& p = set.strokes[k][i];
      if (p.x() < -set.width || p.x() > 2.0 * set.width || p.y() < -set.height ||
          p.y() > 2.0 * set.height) {
        return InvalidArgument("strokes[" + std::to_string(k) + "][" + std::to_string(i) +
                               "]: point (" + Num(p.x(), 1) + ", " + Num(p.y(), 1) +
                               ") lies far outside the " + std::to_string(set.width) + " x " +
                               std::to_string(set.height) +
                               " canvas (allowed: one canvas size beyond each side)");
      }
    }
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
