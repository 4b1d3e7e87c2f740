// Teddy (Igarashi et al. 1999) on the CDT: prune insignificant branches, chordal axis, final
// triangulation typed by spine points (paper figure 10), elevation by distance to the contour.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <unordered_map>

#include "mesh/internal.h"

namespace rheo::mesh::internal {
namespace {

double Cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}
double Orient(const Vec2& a, const Vec2& b, const Vec2& c) {
  return Cross(b - a, c - a);
}
double Angle(const Vec2& c, const Vec2& a, const Vec2& b) {
  return std::atan2(std::abs(Cross(a - c, b - c)), (a - c).dot(b - c));
}

struct Edge {
  int32_t tri = -1;
  int k = -1;  // edge opposite vertex k of tri
};

class Teddy {
 public:
  Teddy(const Cdt& cdt) : c_(cdt) {
    const size_t m = cdt.tri.triangles.size();
    owner_.assign(m, -1);
    absorbed_.assign(m, {0, 0, 0});
    out_.points = cdt.tri.points;
    out_.is_spine.assign(out_.points.size(), 0);
    num_contour_ = static_cast<int32_t>(out_.points.size());
    double len = 0;
    for (const auto& t : cdt.tri.triangles) len = std::max(len, (P(t[1]) - P(t[0])).squaredNorm());
    eps_area_ = 1e-14 * len;
  }

  Result<TeddyTriangulation> Run(double thickness) {
    const auto& cls = c_.tri.classes;
    const size_t m = cls.size();
    for (size_t t = 0; t < m; ++t)
      if (cls[t] == TriangleClass::kIsolated) return Isolated(static_cast<int32_t>(t), thickness);
    for (size_t t = 0; t < m; ++t)
      if (cls[t] == TriangleClass::kTerminal && owner_[t] < 0) {
        if (Status s = Prune(static_cast<int32_t>(t)); !s.ok()) return s.error();
      }
    for (size_t t = 0; t < m; ++t) {
      if (owner_[t] >= 0) continue;
      if (cls[t] == TriangleClass::kSleeve) Sleeve(static_cast<int32_t>(t));
      if (cls[t] == TriangleClass::kJunction) Junction(static_cast<int32_t>(t));
      if (cls[t] == TriangleClass::kTerminal) return Internal("Teddy: terminal triangle unpruned");
    }
    Elevate(thickness);
    return std::move(out_);
  }

 private:
  const Vec2& P(int32_t v) const { return out_.points[v]; }
  int32_t V(int32_t tri, int i) const { return c_.tri.triangles[tri][((i % 3) + 3) % 3]; }
  int32_t Nb(const Edge& e) const { return c_.neighbors[e.tri][e.k]; }
  int32_t A(const Edge& e) const { return V(e.tri, e.k + 1); }
  int32_t B(const Edge& e) const { return V(e.tri, e.k + 2); }

  int32_t NewPoint(const Vec2& p) {
    out_.points.push_back(p);
    out_.is_spine.push_back(1);
    return static_cast<int32_t>(out_.points.size() - 1);
  }
  int32_t Mid(int32_t a, int32_t b) {
    const uint64_t key = (uint64_t(std::min(a, b)) << 32) | uint32_t(std::max(a, b));
    auto [it, fresh] = mids_.try_emplace(key, -1);
    if (fresh) it->second = NewPoint(0.5 * (P(a) + P(b)));
    return it->second;
  }
  int32_t Center(int32_t tri) {
    auto [it, fresh] = centers_.try_emplace(tri, -1);
    if (fresh) {
      it->second = NewPoint((P(V(tri, 0)) + P(V(tri, 1)) + P(V(tri, 2))) / 3.0);
      double h = 0;
      for (int i = 0; i < 3; ++i) h += (P(V(tri, i)) - P(it->second)).norm();
      center_height_[it->second] = h / 3.0;
    }
    return it->second;
  }
  void Emit(int32_t a, int32_t b, int32_t c) { out_.triangles.push_back({a, b, c}); }

  // The contour edges of a region, each as (a, b) counter-clockwise in its triangle.
  std::vector<std::pair<int32_t, int32_t>> ContourEdges(const std::vector<int32_t>& tris) const {
    std::vector<std::pair<int32_t, int32_t>> edges;
    for (int32_t t : tris)
      for (int k = 0; k < 3; ++k)
        if (c_.neighbors[t][k] < 0) edges.emplace_back(V(t, k + 1), V(t, k + 2));
    return edges;
  }

  // A fan from `c` over the region is valid when every triangle is positive and together they
  // sweep exactly the angle that the closing edge (a, b) subtends at c.
  bool FanValid(const std::vector<int32_t>& tris, const Vec2& c, int32_t a, int32_t b) const {
    double sum = 0;
    for (auto [u, v] : ContourEdges(tris)) {
      if (Orient(c, P(u), P(v)) <= eps_area_) return false;
      sum += Angle(c, P(u), P(v));
    }
    return std::abs(sum - Angle(c, P(a), P(b))) < 1e-6;
  }

  Status Prune(int32_t t0) {
    const int32_t rid = static_cast<int32_t>(++regions_);
    std::vector<int32_t> tris{t0};
    owner_[t0] = rid;
    Edge e{t0, -1};
    for (int k = 0; k < 3; ++k)
      if (c_.neighbors[t0][k] >= 0) e.k = k;
    std::vector<Edge> path{e};  // inner edge after each absorbed triangle
    int32_t junction = -1;
    while (true) {
      const int32_t next = Nb(e);
      const Vec2 mid = 0.5 * (P(A(e)) + P(B(e)));
      const double r2 = 0.25 * (P(A(e)) - P(B(e))).squaredNorm() * (1 + 1e-12);
      bool inside = true;
      for (int32_t t : tris)
        for (int i = 0; i < 3 && inside; ++i) inside = (P(V(t, i)) - mid).squaredNorm() <= r2;
      if (!inside || owner_[next] >= 0) break;
      const TriangleClass cls = c_.tri.classes[next];
      if (cls == TriangleClass::kJunction) {
        junction = next;
        break;
      }
      if (cls != TriangleClass::kSleeve) break;  // the other terminal: meet at this edge
      tris.push_back(next);
      owner_[next] = rid;
      Edge n{next, -1};
      for (int k = 0; k < 3; ++k)
        if (c_.neighbors[next][k] >= 0 && c_.neighbors[next][k] != e.tri) n.k = k;
      e = n;
      path.push_back(e);
    }
    if (junction >= 0) {
      const Vec2 cj = (P(V(junction, 0)) + P(V(junction, 1)) + P(V(junction, 2))) / 3.0;
      if (FanValid(tris, cj, A(e), B(e))) {
        const int32_t c = Center(junction);
        for (auto [u, v] : ContourEdges(tris)) Emit(c, u, v);
        for (int k = 0; k < 3; ++k)
          if (c_.neighbors[junction][k] == e.tri) absorbed_[junction][k] = 1;
        ++out_.pruned_branches;
        return Status::Ok();
      }
    }
    // Fan around the midpoint of the inner edge; retreat while that fan would fold.
    while (!FanValid(tris, 0.5 * (P(A(e)) + P(B(e))), A(e), B(e))) {
      if (tris.size() == 1) return Internal("Teddy: terminal triangle cannot be fanned");
      owner_[tris.back()] = -1;
      tris.pop_back();
      path.pop_back();
      e = path.back();
    }
    const int32_t c = Mid(A(e), B(e));
    for (auto [u, v] : ContourEdges(tris)) Emit(c, u, v);
    if (tris.size() > 1) ++out_.pruned_branches;
    return Status::Ok();
  }

  void Sleeve(int32_t t) {
    int k = 0;
    while (c_.neighbors[t][k] >= 0) ++k;
    const int32_t p0 = V(t, k), p1 = V(t, k + 1), p2 = V(t, k + 2);
    const int32_t m01 = Mid(p0, p1), m20 = Mid(p2, p0);
    Emit(p0, m01, m20);
    if ((P(m01) - P(p2)).squaredNorm() <= (P(m20) - P(p1)).squaredNorm()) {
      Emit(m01, p1, p2);
      Emit(m01, p2, m20);
    } else {
      Emit(m20, m01, p1);
      Emit(m20, p1, p2);
    }
    out_.spine_edges.push_back({m01, m20});
  }

  void Junction(int32_t t) {
    const int32_t o = Center(t);
    const bool any = absorbed_[t][0] || absorbed_[t][1] || absorbed_[t][2];
    if (!any) {
      // Paper figure 14: corner triangles, and the midpoint triangle split at an added centre.
      int32_t m[3];  // m[k]: midpoint of the edge opposite vertex k
      for (int k = 0; k < 3; ++k) m[k] = Mid(V(t, k + 1), V(t, k + 2));
      for (int k = 0; k < 3; ++k) {
        Emit(V(t, k), m[(k + 2) % 3], m[(k + 1) % 3]);
        Emit(o, m[(k + 2) % 3], m[k]);
        out_.spine_edges.push_back({o, m[k]});
      }
      return;
    }
    for (int k = 0; k < 3; ++k) {
      if (absorbed_[t][k]) continue;
      const int32_t a = V(t, k + 1), b = V(t, k + 2), mk = Mid(a, b);
      Emit(o, a, mk);
      Emit(o, mk, b);
      out_.spine_edges.push_back({o, mk});
    }
  }

  Result<TeddyTriangulation> Isolated(int32_t t, double thickness) {
    const int32_t o = Center(t);
    for (int k = 0; k < 3; ++k) Emit(o, V(t, k), V(t, k + 1));
    Elevate(thickness);
    return std::move(out_);
  }

  // Each spine vertex rises to the mean distance to the contour vertices it is joined to.
  void Elevate(double thickness) {
    const size_t n = out_.points.size();
    std::vector<std::pair<int32_t, int32_t>> links;
    out_.spine_count.clear();
    for (const auto& tr : out_.triangles) {
      int spines = 0;
      for (int i = 0; i < 3; ++i) {
        if (!out_.is_spine[tr[i]]) continue;
        ++spines;
        for (int j = 0; j < 3; ++j)
          if (!out_.is_spine[tr[j]]) links.emplace_back(tr[i], tr[j]);
      }
      out_.spine_count.push_back(static_cast<uint8_t>(spines));
    }
    std::sort(links.begin(), links.end());
    links.erase(std::unique(links.begin(), links.end()), links.end());
    std::vector<double> sum(n, 0.0);
    std::vector<int> count(n, 0);
    for (auto [s, v] : links) {
      sum[s] += (P(s) - P(v)).norm();
      ++count[s];
    }
    out_.heights.assign(n, 0.0);
    for (size_t v = 0; v < n; ++v) {
      if (!out_.is_spine[v]) continue;
      auto it = center_height_.find(static_cast<int32_t>(v));
      const double h = it != center_height_.end() ? it->second
                       : count[v] > 0             ? sum[v] / count[v]
                                                  : 0.0;
      out_.heights[v] = thickness * h;
    }
  }

  const Cdt& c_;
  TeddyTriangulation out_;
  int32_t num_contour_ = 0;
  double eps_area_ = 0;
  int regions_ = 0;
  std::vector<int32_t> owner_;                    // region of each CDT triangle, -1 none
  std::vector<std::array<uint8_t, 3>> absorbed_;  // junction edges taken by a pruned branch
  std::unordered_map<uint64_t, int32_t> mids_;
  std::unordered_map<int32_t, int32_t> centers_;
  std::unordered_map<int32_t, double> center_height_;
};

}  // namespace

Result<TeddyTriangulation> BuildTeddy(const Cdt& cdt, double thickness) {
  if (cdt.tri.triangles.empty()) return InvalidArgument("Teddy: empty triangulation");
  Teddy teddy(cdt);
  return teddy.Run(thickness);
}

HeightField::HeightField(const TeddyTriangulation& teddy) : t_(teddy) {
  Vec2 hi = teddy.points[0];
  lo_ = hi;
  for (const Vec2& p : teddy.points) {
    lo_ = lo_.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Vec2 ext = (hi - lo_).cwiseMax(1e-12);
  const double ntri = std::max<double>(1, teddy.triangles.size());
  cell_ = std::sqrt(ext.x() * ext.y() / ntri) * 2.0;
  nx_ = std::clamp(static_cast<int>(ext.x() / cell_) + 1, 1, 2048);
  ny_ = std::clamp(static_cast<int>(ext.y() / cell_) + 1, 1, 2048);
  cell_ = std::max(ext.x() / nx_, ext.y() / ny_) * (1 + 1e-9);
  std::vector<std::array<int, 4>> spans;
  start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (const auto& tr : teddy.triangles) {
    Vec2 a = teddy.points[tr[0]], b = a;
    for (int i = 1; i < 3; ++i) {
      a = a.cwiseMin(teddy.points[tr[i]]);
      b = b.cwiseMax(teddy.points[tr[i]]);
    }
    auto ix = [&](double x) {
      return std::clamp(static_cast<int>((x - lo_.x()) / cell_), 0, nx_ - 1);
    };
    auto iy = [&](double y) {
      return std::clamp(static_cast<int>((y - lo_.y()) / cell_), 0, ny_ - 1);
    };
    spans.push_back({ix(a.x()), ix(b.x()), iy(a.y()), iy(b.y())});
    const auto& s = spans.back();
    for (int y = s[2]; y <= s[3]; ++y)
      for (int x = s[0]; x <= s[1]; ++x) ++start_[static_cast<size_t>(y) * nx_ + x + 1];
  }
  for (size_t i = 1; i < start_.size(); ++i) start_[i] += start_[i - 1];
  items_.resize(start_.back());
  std::vector<int32_t> fill(start_.begin(), start_.end() - 1);
  for (size_t t = 0; t < spans.size(); ++t) {
    const auto& s = spans[t];
    for (int y = s[2]; y <= s[3]; ++y)
      for (int x = s[0]; x <= s[1]; ++x)
        items_[fill[static_cast<size_t>(y) * nx_ + x]++] = static_cast<int32_t>(t);
  }
}

double HeightField::operator()(const Vec2& p) const {
  auto bary_min = [&](int32_t t) {
    const auto& tr = t_.triangles[t];
    const Vec2 &a = t_.points[tr[0]], &b = t_.points[tr[1]], &c = t_.points[tr[2]];
    const double area = Orient(a, b, c);
    return std::min({Orient(p, b, c), Orient(a, p, c), Orient(a, b, p)}) / area;
  };
  const int x = std::clamp(static_cast<int>((p.x() - lo_.x()) / cell_), 0, nx_ - 1);
  const int y = std::clamp(static_cast<int>((p.y() - lo_.y()) / cell_), 0, ny_ - 1);
  const size_t cell = static_cast<size_t>(y) * nx_ + x;
  int32_t best = -1;
  double best_v = -1e300;
  for (int32_t i = start_[cell]; i < start_[cell + 1]; ++i) {
    const double v = bary_min(items_[i]);
    if (v > best_v) best_v = v, best = items_[i];
    if (v >= 0) break;
  }
  if (best_v < -1e-9) {  // outside every nearby triangle (rounding at the contour): search all
    for (int32_t t = 0; t < static_cast<int32_t>(t_.triangles.size()); ++t) {
      const double v = bary_min(t);
      if (v > best_v) best_v = v, best = t;
    }
  }
  return best < 0 ? 0.0 : Evaluate(best, p);
}

double HeightField::Evaluate(int32_t tri, const Vec2& p) const {
  const auto& tr = t_.triangles[tri];
  const Vec2 &a = t_.points[tr[0]], &b = t_.points[tr[1]], &c = t_.points[tr[2]];
  const double area = Orient(a, b, c);
  double l[3] = {Orient(p, b, c) / area, Orient(a, p, c) / area, Orient(a, b, p) / area};
  double s = 0;
  for (double& v : l) s += (v = std::max(0.0, v));
  for (double& v : l) v /= s;
  int spine[3], contour[3], ns = 0, nc = 0;
  for (int i = 0; i < 3; ++i) (t_.is_spine[tr[i]] ? spine[ns++] : contour[nc++]) = i;
  auto h = [&](int i) { return t_.heights[tr[i]]; };
  auto oval = [](double u) { return std::sqrt(std::max(0.0, 1.0 - u * u)); };  // quarter ellipse
  switch (ns) {
    case 1: return h(spine[0]) * oval(1.0 - l[spine[0]]);
    case 2: {
      const double w = l[spine[0]] + l[spine[1]];
      const double ridge = w > 0 ? (l[spine[0]] * h(spine[0]) + l[spine[1]] * h(spine[1])) / w
                                 : 0.5 * (h(spine[0]) + h(spine[1]));
      return ridge * oval(l[contour[0]]);
    }
    case 3: return l[0] * h(0) + l[1] * h(1) + l[2] * h(2);
    default: return 0.0;
  }
}

}  // namespace rheo::mesh::internal
