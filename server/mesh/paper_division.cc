// The paper's cells (section 4, figures 10-14): Teddy's final triangulation with each
// spine-to-contour edge cut into rows where its quarter oval is sampled; a triangle with one
// spine point becomes a fan of rows from its contour edge to the spine point (figure 11), one
// with two spine points rings of rows between its contour point and its spine edge (figures
// 12-13), one with three spine points keeps the added centre (figure 14).
#include <cmath>
#include <unordered_map>

#include "mesh/internal.h"

namespace rheo::mesh::internal {
namespace {

double Orient(const Vec2& a, const Vec2& b, const Vec2& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

}  // namespace

Result<Mesh2> PaperMesh(const TeddyTriangulation& t, double row_spacing) {
  Mesh2 out;
  out.tri.points = t.points;
  for (uint8_t s : t.is_spine) out.on_contour.push_back(s ? 0 : 1);
  std::unordered_map<uint64_t, std::vector<int32_t>> chains;
  // Points of the edge from contour vertex c to spine vertex s, c first, s last.
  auto chain = [&](int32_t c, int32_t s) -> const std::vector<int32_t>& {
    const uint64_t key = (uint64_t(uint32_t(c)) << 32) | uint32_t(s);
    auto [it, fresh] = chains.try_emplace(key);
    if (fresh) {
      const Vec2 a = t.points[c], b = t.points[s];
      const int k = std::max(1, static_cast<int>(std::ceil((b - a).norm() / row_spacing)));
      it->second.push_back(c);
      for (int i = 1; i < k; ++i) {
        it->second.push_back(static_cast<int32_t>(out.tri.points.size()));
        out.tri.points.push_back(a + (b - a) * (static_cast<double>(i) / k));
        out.on_contour.push_back(0);
      }
      it->second.push_back(s);
    }
    return it->second;
  };
  auto emit = [&](int32_t a, int32_t b, int32_t c) -> Status {
    const double o = Orient(out.tri.points[a], out.tri.points[b], out.tri.points[c]);
    if (o == 0) return Internal("paper division: degenerate row triangle");
    if (o > 0)
      out.tri.triangles.push_back({a, b, c});
    else
      out.tri.triangles.push_back({a, c, b});
    out.tri.classes.push_back(TriangleClass::kJunction);
    return Status::Ok();
  };
  // Triangulates the strip between rows A[0..na] and B[0..nb], advancing the lower fraction.
  auto ladder = [&](const std::vector<int32_t>& A, int na, const std::vector<int32_t>& B, int nb,
                    int ka, int kb) -> Status {
    int i = 0, j = 0;
    while (i < na || j < nb) {
      const bool advance_a =
          j >= nb || (i < na && static_cast<double>(i + 1) / ka <= static_cast<double>(j + 1) / kb);
      Status s = advance_a ? emit(A[i], B[j], A[i + 1]) : emit(A[i], B[j], B[j + 1]);
      if (!s.ok()) return s;
      (advance_a ? i : j)++;
    }
    return Status::Ok();
  };
  for (size_t k = 0; k < t.triangles.size(); ++k) {
    const auto& tr = t.triangles[k];
    int spine[3], contour[3], ns = 0, nc = 0;
    for (int i = 0; i < 3; ++i) (t.is_spine[tr[i]] ? spine[ns++] : contour[nc++]) = tr[i];
    Status s;
    if (ns == 1) {
      const auto A = chain(contour[0], spine[0]), B = chain(contour[1], spine[0]);
      const int ka = static_cast<int>(A.size()) - 1, kb = static_cast<int>(B.size()) - 1;
      s = ladder(A, ka - 1, B, kb - 1, ka, kb);
      if (s.ok()) s = emit(A[ka - 1], B[kb - 1], spine[0]);
    } else if (ns == 2) {
      const auto A = chain(contour[0], spine[0]), B = chain(contour[0], spine[1]);
      const int ka = static_cast<int>(A.size()) - 1, kb = static_cast<int>(B.size()) - 1;
      // Rows start at the shared contour point: first triangle, then the ring strip.
      s = emit(contour[0], A[1], B[1]);
      if (s.ok()) {
        const std::vector<int32_t> a2(A.begin() + 1, A.end()), b2(B.begin() + 1, B.end());
        s = ladder(a2, ka - 1, b2, kb - 1, ka, kb);
      }
    } else {
      s = emit(tr[0], tr[1], tr[2]);
    }
    if (!s.ok()) return s.error();
  }
  return out;
}

}  // namespace rheo::mesh::internal
