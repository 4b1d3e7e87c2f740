#include "sketch/polyline.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace rheo::sketch::internal {
namespace {

// Edges of a closed polygon binned in a uniform grid of about one cell per edge; an edge is
// listed in every cell its pieces (no longer than a cell) touch.
class EdgeGrid {
 public:
  EdgeGrid(const std::vector<Vec2>& p, double min_cell) {
    const int n = static_cast<int>(p.size());
    double perimeter = 0.0;
    for (int i = 0; i < n; ++i) box_.extend(p[i]), perimeter += (p[(i + 1) % n] - p[i]).norm();
    const Vec2 ext = box_.max() - box_.min();
    // At most about 3n cells and 5n entries, whatever the shape.
    cell_ = std::max({std::sqrt(ext.x() * ext.y() / std::max(1, n)),
                      std::max(ext.x(), ext.y()) / std::max(1, n), perimeter / (4.0 * n), min_cell,
                      1e-9});
    nx_ = static_cast<int>(ext.x() / cell_) + 1;
    ny_ = static_cast<int>(ext.y() / cell_) + 1;
    std::vector<std::pair<int, int>> entries;
    for (int i = 0; i < n; ++i) {
      const Vec2& a = p[i];
      const Vec2& b = p[(i + 1) % n];
      const int pieces = static_cast<int>(std::ceil((b - a).norm() / cell_)) + 1;
      for (int m = 0; m < pieces; ++m) {
        const Vec2 u = a + (b - a) * (double(m) / pieces);
        const Vec2 v = a + (b - a) * (double(m + 1) / pieces);
        for (int y = CellY(std::min(u.y(), v.y())); y <= CellY(std::max(u.y(), v.y())); ++y)
          for (int x = CellX(std::min(u.x(), v.x())); x <= CellX(std::max(u.x(), v.x())); ++x) {
            const int c = y * nx_ + x;
            if (entries.empty() || entries.back() != std::make_pair(c, i))
              entries.emplace_back(c, i);
          }
      }
    }
    start_.assign(size_t(nx_) * ny_ + 1, 0);
    for (const auto& e : entries) ++start_[e.first + 1];
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(entries.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (const auto& e : entries) items_[fill[e.first]++] = e.second;
  }
  int CellX(double x) const {
    return std::clamp(static_cast<int>(std::floor((x - box_.min().x()) / cell_)), 0, nx_ - 1);
  }
  int CellY(double y) const {
    return std::clamp(static_cast<int>(std::floor((y - box_.min().y()) / cell_)), 0, ny_ - 1);
  }
  double cell() const { return cell_; }
  // Calls f(edge) for the edges listed in the cells that the box lo..hi overlaps.
  template <typename F>
  void ForEach(const Vec2& lo, const Vec2& hi, F f) const {
    for (int y = CellY(lo.y()); y <= CellY(hi.y()); ++y)
      for (int x = CellX(lo.x()); x <= CellX(hi.x()); ++x) {
        const int c = y * nx_ + x;
        for (int k = start_[c]; k < start_[c + 1]; ++k) f(items_[k]);
      }
  }

 private:
  Eigen::AlignedBox2d box_;
  double cell_ = 1.0;
  int nx_ = 1, ny_ = 1;
  std::vector<int> start_, items_;
};

}  // namespace

double SignedArea(const std::vector<Vec2>& p) {
  const size_t n = p.size();
  double a = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const Vec2& u = p[i];
    const Vec2& v = p[(i + 1) % n];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * a;
}

double OpenLength(const std::vector<Vec2>& p) {
  double l = 0.0;
  for (size_t i = 1; i < p.size(); ++i) l += (p[i] - p[i - 1]).norm();
  return l;
}

double ClosedLength(const std::vector<Vec2>& p) {
  if (p.size() < 2) return 0.0;
  return OpenLength(p) + (p.front() - p.back()).norm();
}

double PointSegmentDistance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 d = b - a;
  const double l2 = d.squaredNorm();
  double t = l2 > 0.0 ? (p - a).dot(d) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (p - (a + t * d)).norm();
}

double PointPolygonDistance(const Vec2& p, const std::vector<Vec2>& poly) {
  double best = INFINITY;
  const size_t n = poly.size();
  for (size_t i = 0; i < n; ++i) {
    best = std::min(best, PointSegmentDistance(p, poly[i], poly[(i + 1) % n]));
  }
  return best;
}

static double Cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

std::optional<SegmentHit> IntersectSegments(const Vec2& a, const Vec2& b, const Vec2& c,
                                            const Vec2& d) {
  const Vec2 r = b - a;
  const Vec2 s = d - c;
  const double den = Cross(r, s);
  const Vec2 ca = c - a;
  if (std::abs(den) < 1e-12 * (r.squaredNorm() + s.squaredNorm())) {
    // Parallel: report collinear overlap at its first point.
    if (std::abs(Cross(ca, r)) > 1e-9 * (1.0 + r.norm() * ca.norm())) return std::nullopt;
    const double rr = r.squaredNorm();
    if (rr == 0.0) return std::nullopt;
    const double t0 = ca.dot(r) / rr;
    const double t1 = (d - a).dot(r) / rr;
    const double lo = std::max(0.0, std::min(t0, t1));
    const double hi = std::min(1.0, std::max(t0, t1));
    if (lo > hi) return std::nullopt;
    const Vec2 pt = a + lo * r;
    const double ss = s.squaredNorm();
    const double u = ss > 0.0 ? (pt - c).dot(s) / ss : 0.0;
    return SegmentHit{pt, lo, std::clamp(u, 0.0, 1.0)};
  }
  const double t = Cross(ca, s) / den;
  const double u = Cross(ca, r) / den;
  if (t < 0.0 || t > 1.0 || u < 0.0 || u > 1.0) return std::nullopt;
  return SegmentHit{a + t * r, t, u};
}

std::vector<Vec2> ResampleClosed(const std::vector<Vec2>& p, double spacing) {
  const double total = ClosedLength(p);
  const int n = std::max(8, static_cast<int>(std::ceil(total / spacing)));
  const double step = total / n;
  std::vector<Vec2> out;
  out.reserve(n);
  size_t i = 0;  // current edge from p[i] to p[i+1 mod size]
  double edge_start = 0.0;
  double edge_len = (p[1 % p.size()] - p[0]).norm();
  for (int k = 0; k < n; ++k) {
    const double s = k * step;
    while (edge_start + edge_len < s && i + 1 < p.size()) {
      edge_start += edge_len;
      ++i;
      edge_len = (p[(i + 1) % p.size()] - p[i]).norm();
    }
    const double t = edge_len > 0.0 ? std::clamp((s - edge_start) / edge_len, 0.0, 1.0) : 0.0;
    out.push_back(p[i] + t * (p[(i + 1) % p.size()] - p[i]));
  }
  return out;
}

std::vector<int> SimplifyClosed(const std::vector<Vec2>& chain, double epsilon,
                                double* max_distance, const CancelToken& cancel) {
  const int n = static_cast<int>(chain.size());
  double worst = 0.0;
  if (n <= 3) {
    std::vector<int> all(n);
    for (int i = 0; i < n; ++i) all[i] = i;
    if (max_distance) *max_distance = 0.0;
    return all;
  }
  // P1 = chain[0]; Pm = the chain point farthest from it splits the loop into two open runs.
  int m = 1;
  double far = -1.0;
  for (int i = 1; i < n; ++i) {
    const double d = (chain[i] - chain[0]).squaredNorm();
    if (d > far) far = d, m = i;
  }
  std::vector<char> keep(n, 0);
  keep[0] = keep[m] = 1;
  struct Span {
    int first, last;  // indices into the unrolled chain (last may be n, meaning 0)
  };
  std::vector<Span> stack = {{0, m}, {m, n}};
  int64_t work = 0;  // points measured since the last look at the token
  while (!stack.empty()) {
    if (work > (1 << 16)) {
      if (cancel.stop_requested()) break;
      work = 0;
    }
    const Span sp = stack.back();
    stack.pop_back();
    const Vec2& a = chain[sp.first];
    const Vec2& b = chain[sp.last % n];
    double hmax = -1.0;
    int split = -1;
    work += sp.last - sp.first;
    for (int i = sp.first + 1; i < sp.last; ++i) {
      const double h = PointSegmentDistance(chain[i], a, b);
      if (h > hmax) hmax = h, split = i;
    }
    if (split < 0) continue;
    if (hmax > epsilon) {
      keep[split] = 1;
      stack.push_back({sp.first, split});
      stack.push_back({split, sp.last});
    } else {
      worst = std::max(worst, hmax);
    }
  }
  std::vector<int> idx;
  for (int i = 0; i < n; ++i)
    if (keep[i]) idx.push_back(i);
  if (max_distance) *max_distance = worst;
  return idx;
}

std::optional<Crossing> FindSelfCrossing(const std::vector<Vec2>& p, const CancelToken& cancel) {
  const int n = static_cast<int>(p.size());
  if (n < 4) return std::nullopt;
  const EdgeGrid grid(p, 0.0);
  std::vector<int> seen(n, -1);  // the edge i that last compared with edge j
  for (int i = 0; i < n; ++i) {
    if ((i & 255) == 255 && cancel.stop_requested()) return std::nullopt;
    const Vec2& a = p[i];
    const Vec2& b = p[(i + 1) % n];
    const double minx = std::min(a.x(), b.x()), maxx = std::max(a.x(), b.x());
    const double miny = std::min(a.y(), b.y()), maxy = std::max(a.y(), b.y());
    // The lowest j > i + 1 whose edge crosses edge i; edges sharing no cell cannot touch it.
    int best_j = n;
    std::optional<SegmentHit> best_hit;
    grid.ForEach(Vec2(minx, miny), Vec2(maxx, maxy), [&](int j) {
      if (j < i + 2 || j >= best_j || seen[j] == i) return;
      seen[j] = i;
      if (i == 0 && j == n - 1) return;  // adjacent through the closing edge
      const Vec2& c = p[j];
      const Vec2& d = p[(j + 1) % n];
      if (std::max(c.x(), d.x()) < minx || std::min(c.x(), d.x()) > maxx ||
          std::max(c.y(), d.y()) < miny || std::min(c.y(), d.y()) > maxy) {
        return;
      }
      if (auto hit = IntersectSegments(a, b, c, d)) best_j = j, best_hit = hit;
    });
    if (best_hit) return Crossing{i, best_j, best_hit->point};
  }
  return std::nullopt;
}

double MaxNearDistance(const std::vector<Vec2>& points, const std::vector<Vec2>& poly, double reach,
                       const CancelToken& cancel) {
  const int n = static_cast<int>(poly.size());
  if (n == 0) return 0.0;
  const EdgeGrid grid(poly, reach);
  double worst = 0.0;
  for (size_t k = 0; k < points.size(); ++k) {
    if ((k & 1023) == 1023 && cancel.stop_requested()) break;
    const Vec2& q = points[k];
    // The nearest edge, if it is within reach, is listed in a cell within reach of q.
    double d = INFINITY;
    grid.ForEach(q - Vec2(reach, reach), q + Vec2(reach, reach), [&](int i) {
      d = std::min(d, PointSegmentDistance(q, poly[i], poly[(i + 1) % n]));
    });
    if (d <= reach) worst = std::max(worst, d);
  }
  return worst;
}

void RemoveNearDuplicates(std::vector<Vec2>& p, double min_spacing) {
  if (p.empty()) return;
  std::vector<Vec2> out;
  out.reserve(p.size());
  out.push_back(p[0]);
  for (size_t i = 1; i < p.size(); ++i) {
    if ((p[i] - out.back()).norm() >= min_spacing) out.push_back(p[i]);
  }
  while (out.size() > 1 && (out.back() - out.front()).norm() < min_spacing) out.pop_back();
  p = std::move(out);
}

}  // namespace rheo::sketch::internal
