#include "haptics/closest_point.h"

namespace rheo::haptics::internal {
namespace {

ClosestPoint OnSegment(const Vec3& p, const Vec3& a, const Vec3& b, int ia, int ib, Feature edge,
                       Feature va, Feature vb) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  double t = len2 > 0.0 ? (p - a).dot(ab) / len2 : 0.0;
  ClosestPoint r;
  r.bary.setZero();
  if (t <= 0.0) {
    t = 0.0;
    r.feature = va;
  } else if (t >= 1.0) {
    t = 1.0;
    r.feature = vb;
  } else {
    r.feature = edge;
  }
  r.point = a + t * ab;
  r.bary[ia] = 1.0 - t;
  r.bary[ib] = t;
  return r;
}

}  // namespace

ClosestPoint ClosestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  ClosestPoint r;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    r.point = a;
    r.bary = Vec3(1, 0, 0);
    r.feature = Feature::kVertex0;
    return r;
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) {
    r.point = b;
    r.bary = Vec3(0, 1, 0);
    r.feature = Feature::kVertex1;
    return r;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    r.point = a + v * ab;
    r.bary = Vec3(1 - v, v, 0);
    r.feature = Feature::kEdge0;
    return r;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) {
    r.point = c;
    r.bary = Vec3(0, 0, 1);
    r.feature = Feature::kVertex2;
    return r;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    r.point = a + w * ac;
    r.bary = Vec3(1 - w, 0, w);
    r.feature = Feature::kEdge2;
    return r;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    r.point = b + w * (c - b);
    r.bary = Vec3(0, 1 - w, w);
    r.feature = Feature::kEdge1;
    return r;
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) {
    // Degenerate (zero-area) triangle: the closest point lies on one of its edges.
    ClosestPoint best =
        OnSegment(p, a, b, 0, 1, Feature::kEdge0, Feature::kVertex0, Feature::kVertex1);
    for (const ClosestPoint& e :
         {OnSegment(p, b, c, 1, 2, Feature::kEdge1, Feature::kVertex1, Feature::kVertex2),
          OnSegment(p, c, a, 2, 0, Feature::kEdge2, Feature::kVertex2, Feature::kVertex0)}) {
      if ((e.point - p).squaredNorm() < (best.point - p).squaredNorm()) best = e;
    }
    return best;
  }
  const double denom = 1.0 / sum;
  const double v = vb * denom, w = vc * denom;
  r.point = a + ab * v + ac * w;
  r.bary = Vec3(1 - v - w, v, w);
  r.feature = Feature::kFace;
  return r;
}

}  // namespace rheo::haptics::internal
