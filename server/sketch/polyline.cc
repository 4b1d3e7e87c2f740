#include "sketch/polyline.h"

#include <algorithm>
#include <cmath>

namespace rheo::sketch::internal {

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
                                double* max_distance) {
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
  while (!stack.empty()) {
    const Span sp = stack.back();
    stack.pop_back();
    const Vec2& a = chain[sp.first];
    const Vec2& b = chain[sp.last % n];
    double hmax = -1.0;
    int split = -1;
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

std::optional<Crossing> FindSelfCrossing(const std::vector<Vec2>& p) {
  const int n = static_cast<int>(p.size());
  if (n < 4) return std::nullopt;
  for (int i = 0; i < n; ++i) {
    const Vec2& a = p[i];
    const Vec2& b = p[(i + 1) % n];
    const double minx = std::min(a.x(), b.x()), maxx = std::max(a.x(), b.x());
    const double miny = std::min(a.y(), b.y()), maxy = std::max(a.y(), b.y());
    for (int j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // adjacent through the closing edge
      const Vec2& c = p[j];
      const Vec2& d = p[(j + 1) % n];
      if (std::max(c.x(), d.x()) < minx || std::min(c.x(), d.x()) > maxx ||
          std::max(c.y(), d.y()) < miny || std::min(c.y(), d.y()) > maxy) {
        continue;
      }
      if (auto hit = IntersectSegments(a, b, c, d)) return Crossing{i, j, hit->point};
    }
  }
  return std::nullopt;
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
