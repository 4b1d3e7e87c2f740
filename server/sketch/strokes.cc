#include "sketch/strokes.h"

#include <simdjson.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <deque>
#include <nlohmann/json.hpp>
#include <optional>

#include "common/cancel.h"
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

// The outline being grown: appends and trims at the end, and reverses in O(1) (logical point i
// is d_[n - 1 - i] when reversed), so a join costs the points it touches, not the chain's length.
class GrowingChain {
 public:
  explicit GrowingChain(const std::vector<Vec2>& p)
      : d_(p.begin(), p.end()), length_(OpenLength(p)) {}
  int size() const { return static_cast<int>(d_.size()); }
  const Vec2& operator[](int i) const { return rev_ ? d_[d_.size() - 1 - i] : d_[i]; }
  const Vec2& front() const { return (*this)[0]; }
  const Vec2& back() const { return (*this)[size() - 1]; }
  double length() const { return length_; }
  void Reverse() { rev_ = !rev_; }
  void PopBack() {
    if (size() >= 2) length_ -= (back() - (*this)[size() - 2]).norm();
    rev_ ? d_.pop_front() : d_.pop_back();
  }
  void PushBack(const Vec2& p) {
    if (!d_.empty()) length_ += (p - back()).norm();
    rev_ ? d_.push_front(p) : d_.push_back(p);
  }
  std::vector<Vec2> ToVector() const {
    std::vector<Vec2> out;
    out.reserve(d_.size());
    for (int i = 0; i < size(); ++i) out.push_back((*this)[i]);
    return out;
  }
  // The chain as BestJoin's `a` sees it (reversed when `head`), from TailStart(a, w) to its end;
  // *first receives that start index in `a`.
  std::vector<Vec2> EndWindow(bool head, double w, int* first) const {
    const int n = size();
    auto at = [&](int k) -> const Vec2& { return head ? (*this)[n - 1 - k] : (*this)[k]; };
    double l = 0.0;
    int i = n - 1;
    while (i > 0 && l + (at(i) - at(i - 1)).norm() <= w) l += (at(i) - at(i - 1)).norm(), --i;
    *first = std::max(0, i - 1);
    std::vector<Vec2> out;
    out.reserve(n - *first);
    for (int k = *first; k < n; ++k) out.push_back(at(k));
    return out;
  }

 private:
  std::deque<Vec2> d_;
  bool rev_ = false;
  double length_ = 0.0;
};

// The leading part of p (reversed when `rev`) that BestJoin reads: points 0..HeadEnd(b, w).
std::vector<Vec2> HeadWindow(const std::vector<Vec2>& p, bool rev, double w) {
  const int n = static_cast<int>(p.size());
  auto at = [&](int k) -> const Vec2& { return rev ? p[n - 1 - k] : p[k]; };
  double l = 0.0;
  int i = 0;
  while (i + 1 < n && l + (at(i + 1) - at(i)).norm() <= w) l += (at(i + 1) - at(i)).norm(), ++i;
  const int last = std::min(n - 1, i + 1);
  std::vector<Vec2> out;
  out.reserve(last + 1);
  for (int k = 0; k <= last; ++k) out.push_back(at(k));
  return out;
}

double BoxDistance(const Eigen::AlignedBox2d& a, const Eigen::AlignedBox2d& b) {
  const double dx = std::max({0.0, a.min().x() - b.max().x(), b.min().x() - a.max().x()});
  const double dy = std::max({0.0, a.min().y() - b.max().y(), b.min().y() - a.max().y()});
  return std::hypot(dx, dy);
}

// Uniform grid over the strokes: each stroke is listed in the cells its segments pass through
// (segments cut into pieces no longer than a cell). About one cell per stroke, so finding the
// strokes near a chain end costs what lies near it, not the whole drawing. A stroke that would
// fill too many cells is kept in a short list checked by its bounding box instead.
class StrokeGrid {
 public:
  StrokeGrid(const std::vector<std::vector<Vec2>>& strokes) {
    const int n = static_cast<int>(strokes.size());
    double total = 0.0;
    for (const auto& s : strokes) {
      for (const Vec2& q : s) box_.extend(q);
      total += OpenLength(s);
    }
    const Vec2 ext = box_.max() - box_.min();
    const double w = std::max(ext.x(), 0.0), h = std::max(ext.y(), 0.0);
    // At most about 3n cells and 4n + (segments) entries, whatever the drawing.
    cell_ = std::max({std::sqrt(w * h / n), std::max(w, h) / n, total / (4.0 * n), 1e-6});
    nx_ = static_cast<int>(w / cell_) + 1;
    ny_ = static_cast<int>(h / cell_) + 1;
    const int64_t cap = 16 + 8 * static_cast<int64_t>(std::sqrt(double(n)));
    std::vector<std::pair<int, int>> entries;  // (cell, stroke)
    for (int s = 0; s < n; ++s) {
      const size_t mark = entries.size();
      bool big = false;
      const auto& p = strokes[s];
      for (size_t k = 0; k + 1 < p.size() && !big; ++k) {
        const double len = (p[k + 1] - p[k]).norm();
        const int pieces = static_cast<int>(std::min(1e9, std::ceil(len / cell_))) + 1;
        if (pieces > cap) {
          big = true;
          break;
        }
        for (int m = 0; m < pieces && !big; ++m) {
          const Vec2 u = p[k] + (p[k + 1] - p[k]) * (double(m) / pieces);
          const Vec2 v = p[k] + (p[k + 1] - p[k]) * (double(m + 1) / pieces);
          const int x0 = CellX(std::min(u.x(), v.x())), x1 = CellX(std::max(u.x(), v.x()));
          const int y0 = CellY(std::min(u.y(), v.y())), y1 = CellY(std::max(u.y(), v.y()));
          for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
              const int c = y * nx_ + x;
              if (entries.size() == mark || entries.back() != std::make_pair(c, s))
                entries.emplace_back(c, s);
            }
          big = static_cast<int64_t>(entries.size() - mark) > 4 * cap;
        }
      }
      if (big) {
        entries.resize(mark);
        big_.push_back(s);
      }
    }
    start_.assign(size_t(nx_) * ny_ + 1, 0);
    for (const auto& e : entries) ++start_[e.first + 1];
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(entries.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (const auto& e : entries) items_[fill[e.first]++] = e.second;
  }

  /// Calls visit(stroke) for the strokes listed within ring k of `near`'s cells, ring by ring,
  /// while keep_going(distance) holds, where every stroke not yet visited lies farther than
  /// `distance` from `near`. A cell lists its strokes in increasing order; visit returns false to
  /// skip the rest of the cell. Strokes are visited once or more (the caller dedups); the big
  /// ones are not visited (big()).
  template <typename Visit, typename KeepGoing>
  void Rings(const Eigen::AlignedBox2d& near, Visit visit, KeepGoing keep_going) const {
    const int x0 = CellX(near.min().x()), x1 = CellX(near.max().x());
    const int y0 = CellY(near.min().y()), y1 = CellY(near.max().y());
    for (int k = 0;; ++k) {
      const int ax = x0 - k, bx = x1 + k, ay = y0 - k, by = y1 + k;
      for (int y = std::max(ay, 0); y <= std::min(by, ny_ - 1); ++y) {
        const bool edge_row = k == 0 || y == ay || y == by;
        for (int x = std::max(ax, 0); x <= std::min(bx, nx_ - 1); ++x) {
          if (!edge_row && x != ax && x != bx) {
            x = std::max(x, bx - 1);  // skip the inside, visited in earlier rings
            continue;
          }
          const int c = y * nx_ + x;
          for (int i = start_[c]; i < start_[c + 1]; ++i)
            if (!visit(items_[i])) break;
        }
      }
      if (ax <= 0 && ay <= 0 && bx >= nx_ - 1 && by >= ny_ - 1) return;  // covered everything
      if (!keep_going(k * cell_)) return;
    }
  }
  const std::vector<int>& big() const { return big_; }

 private:
  int CellX(double x) const {
    return std::clamp(static_cast<int>((x - box_.min().x()) / cell_), 0, nx_ - 1);
  }
  int CellY(double y) const {
    return std::clamp(static_cast<int>((y - box_.min().y()) / cell_), 0, ny_ - 1);
  }

  Eigen::AlignedBox2d box_;
  double cell_ = 1.0;
  int nx_ = 1, ny_ = 1;
  std::vector<int> start_;  // per cell, its first entry in items_ (CSR)
  std::vector<int> items_;  // stroke indices
  std::vector<int> big_;    // strokes listed in no cell
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

  if (static_cast<int64_t>(strokes.size()) > options.max_strokes)
    return ResourceExhausted("the sketch has " + std::to_string(strokes.size()) +
                             " strokes, over the limit of " + std::to_string(options.max_strokes) +
                             " (max_strokes)");
  const int n = static_cast<int>(strokes.size());
  CancelPoll poll(options.cancel, "stroke merging", 64);
  std::vector<double> len(n);
  std::vector<Eigen::AlignedBox2d> boxes(n);
  double longest = 0.0;
  for (int s = 0; s < n; ++s) {
    len[s] = OpenLength(strokes[s]);
    longest = std::max(longest, len[s]);
    for (const Vec2& q : strokes[s]) boxes[s].extend(q);
  }
  // Seeds: the longest unused stroke first (the lower index on ties).
  std::vector<int> by_length(n);
  for (int s = 0; s < n; ++s) by_length[s] = s;
  std::stable_sort(by_length.begin(), by_length.end(),
                   [&](int x, int y) { return len[x] > len[y]; });
  const StrokeGrid grid(strokes);
  std::vector<char> used(n, 0);
  std::vector<uint32_t> seen(n, 0);  // stamp of the last search that evaluated the stroke
  uint32_t search = 0;
  std::vector<Chain> chains;
  const double frac = options.max_gap_fraction;
  size_t next_seed = 0;
  for (;;) {
    while (next_seed < by_length.size() && used[by_length[next_seed]]) ++next_seed;
    if (next_seed == by_length.size()) break;
    const int seed = by_length[next_seed];
    used[seed] = 1;
    Chain chain{{}, {ids[seed]}, {}};
    GrowingChain pts(strokes[seed]);
    for (;;) {
      if (poll.StopNow()) return poll.error();
      const double lc = pts.length();
      // Each stroke s is tried at both chain ends and in both directions; the join with the
      // smallest gap within its closing limit wins (ties: lowest s, then tail before head, then
      // forward before reversed). BestJoin reads only a window at each end, no wider than
      // w_max, so a stroke whose bounding box is farther from that window than the best gap
      // so far cannot win and is not tried.
      const double w_max = std::min({0.35 * lc, 0.35 * longest, 0.05 * (lc + longest) + 15.0});
      const double limit_max = frac * (lc + longest);
      int best = -1;
      bool best_head = false, best_rev = false;
      Join best_join;
      std::vector<Vec2> window[2];
      int first[2] = {0, 0};
      for (int head = 0; head < 2; ++head) window[head] = pts.EndWindow(head, w_max, &first[head]);
      auto better = [&](const Join& j, int s, int head, int rev) {
        if (j.gap != best_join.gap) return j.gap < best_join.gap;
        if (s != best) return s < best;
        if (head != int(best_head)) return head < int(best_head);
        return rev < int(best_rev);
      };
      auto try_stroke = [&](int s, int head) {
        const double w = std::min({0.35 * lc, 0.35 * len[s], 0.05 * (lc + len[s]) + 15.0});
        const double limit = frac * (lc + len[s]);
        const Vec2 end = head ? pts.front() : pts.back();
        for (int rev = 0; rev < 2; ++rev) {
          const Vec2 sb = rev ? strokes[s].back() : strokes[s].front();
          if ((end - sb).norm() > limit + 2.0 * w) continue;  // cannot be within reach
          Join j = BestJoin(window[head], HeadWindow(strokes[s], rev, w), w);
          j.cut_a.i += first[head];
          if (j.gap <= limit && (best < 0 || better(j, s, head, rev))) {
            best_join = j, best = s, best_head = head, best_rev = rev;
          }
        }
      };
      bool stop = false;
      for (int head = 0; head < 2 && !stop; ++head) {
        Eigen::AlignedBox2d near;
        for (const Vec2& q : window[head]) near.extend(q);
        ++search;
        grid.Rings(
            near,
            [&](int s) {
              // Gap 0 (ends that cross) cannot be beaten; a higher index only ties and loses.
              if (stop || (best >= 0 && best_join.gap == 0.0 && s > best)) return false;
              if (used[s] || seen[s] == search) return true;
              seen[s] = search;
              if (poll.Stop()) {
                stop = true;
                return false;
              }
              try_stroke(s, head);
              return true;
            },
            [&](double distance) {
              return !stop && distance < limit_max && (best < 0 || distance < best_join.gap);
            });
        for (int s : grid.big()) {
          if (used[s] || stop) continue;
          const double lower = BoxDistance(near, boxes[s]);
          if (lower > limit_max || (best >= 0 && lower > best_join.gap)) continue;
          if (poll.Stop()) stop = true;
          try_stroke(s, head);
        }
      }
      if (stop) return poll.error();
      if (best < 0) break;
      // Splice in place: keep the chain up to cut_a, bridge to cut_b, continue along the stroke;
      // near-duplicate points (under 1e-6 px) are dropped where the two meet.
      if (best_head) pts.Reverse();
      std::vector<Vec2> b = strokes[best];
      if (best_rev) std::reverse(b.begin(), b.end());
      const Cut ca = best_join.cut_a, cb = best_join.cut_b;
      const int na = pts.size();
      const Vec2 pa = ca.i + 1 >= na ? pts.back() : pts[ca.i] + ca.t * (pts[ca.i + 1] - pts[ca.i]);
      const Vec2 pb = At(b, cb);
      while (pts.size() > std::min(ca.i + 1, na)) pts.PopBack();
      Vec2 raw_last = pts.back();
      auto append = [&](const Vec2& q) {
        if ((q - pts.back()).norm() > 1e-6) pts.PushBack(q);
      };
      if (ca.i + 1 < na && ca.t > 0.0) append(pa), raw_last = pa;
      if ((raw_last - pb).norm() > 1e-9) append(pb);
      for (size_t k = cb.i + 1; k < b.size(); ++k) append(b[k]);
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
    chain.pts = pts.ToVector();
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
