#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <unordered_map>

#include "common/format.h"
#include "haptics/closest_point.h"
#include "haptics/haptics.h"

namespace rheo::haptics {
namespace {

using internal::ClosestPoint;
using internal::ClosestPointOnTriangle;
using internal::Feature;
using internal::HalfSpace;

constexpr double kDepthTol = 1e-10;   // penetration tolerated before pushing the proxy out [m]
constexpr double kTouch = 1e-8;       // gap below which a face touches the proxy [m]
constexpr double kProjTol = 1e-12;    // feasibility tolerance of the projection [m]
constexpr double kMinMove = 1e-12;    // displacement treated as no motion [m]
constexpr double kSettle = 0.1;       // final approach to the surface, in tool radii
constexpr double kRelinearise = 0.5;  // longest step on one linearisation, in tool radii
constexpr int kMaxDepenetration = 16;
constexpr int kMaxMoves = 24;

// Error text: "<field> = <value> <unit> is outside <range>".
Status Range(const char* field, double v, const char* unit, const char* range) {
  return InvalidArgument(std::string("RendererConfig.") + field + " = " + Num(v) + " " + unit +
                         " is outside " + range);
}

bool In(double v, double lo, double hi, bool lo_open, bool hi_open) {
  if (!std::isfinite(v)) return false;
  if (lo_open ? v <= lo : v < lo) return false;
  if (hi_open ? v >= hi : v > hi) return false;
  return true;
}

bool Finite(const Vec3& v) {
  return v.allFinite();
}

}  // namespace

Status RendererConfig::Validate() const {
  const DeviceLimits& d = device;
  if (!In(d.max_force, 0, 1000, true, false))
    return Range("device.max_force", d.max_force, "N", "(0, 1000]");
  if (!In(d.max_stiffness, 0, 1e6, true, false))
    return Range("device.max_stiffness", d.max_stiffness, "N/m", "(0, 1e6]");
  if (!In(d.max_force_rate, 0, 1e7, true, false))
    return Range("device.max_force_rate", d.max_force_rate, "N/s", "(0, 1e7]");
  if (!In(d.damping, 0, 1000, true, false))
    return Range("device.damping", d.damping, "N s/m", "(0, 1000]");
  if (!In(d.tick, 1e-5, 0.1, false, false)) return Range("device.tick", d.tick, "s", "[1e-5, 0.1]");
  if (!In(tool_radius, 0, 0.1, true, false))
    return Range("tool_radius", tool_radius, "m", "(0, 0.1]");
  if (!In(coupling_stiffness, 0, 1e7, true, false))
    return Range("coupling_stiffness", coupling_stiffness, "N/m", "(0, 1e7]");
  if (!In(coupling_damping, 0, d.damping, false, true))
    return Range("coupling_damping", coupling_damping, "N s/m",
                 ("[0, device.damping = " + Num(d.damping) + ")").c_str());
  if (!In(stability_margin, 0, 1, true, false))
    return Range("stability_margin", stability_margin, "", "(0, 1]");
  if (!In(static_friction, 0, 2, false, false))
    return Range("static_friction", static_friction, "", "[0, 2]");
  if (!In(dynamic_friction, 0, static_friction, false, false))
    return Range("dynamic_friction", dynamic_friction, "",
                 ("[0, static_friction = " + Num(static_friction) + "]").c_str());
  if (!In(max_step, 0, 0.1, true, false)) return Range("max_step", max_step, "m", "(0, 0.1]");
  if (!In(max_surface_speed, 0, 100, false, false))
    return Range("max_surface_speed", max_surface_speed, "m/s", "[0, 100]");
  if (rebin_faces_per_tick < 1 || rebin_faces_per_tick > 100000000)
    return Range("rebin_faces_per_tick", rebin_faces_per_tick, "faces", "[1, 1e8]");
  if (!(cell_size == 0.0 || In(cell_size, 0, 1, true, false)))
    return Range("cell_size", cell_size, "m", "0 (automatic) or (0, 1]");
  return Status::Ok();
}

Result<Renderer> Renderer::Create(const RendererConfig& config,
                                  std::span<const std::array<int32_t, 3>> triangles,
                                  std::span<const Vec3> positions, const Vec3& tool) {
  if (Status s = config.Validate(); !s.ok()) return s.error();
  if (triangles.size() < 4)
    return InvalidArgument("surface has " + std::to_string(triangles.size()) +
                           " triangles; a closed surface needs at least 4");
  if (triangles.size() > 100000000) return ResourceExhausted("surface has over 1e8 triangles");
  const int32_t n = static_cast<int32_t>(positions.size());
  for (int32_t i = 0; i < n; ++i) {
    if (!Finite(positions[i]))
      return InvalidArgument("node " + std::to_string(i) + " has a non-finite position");
  }
  if (!Finite(tool)) return InvalidArgument("tool position is not finite");

  Renderer r;
  r.config_ = config;
  r.node_count_ = n;
  r.tris_.assign(triangles.begin(), triangles.end());
  const int32_t m = static_cast<int32_t>(r.tris_.size());

  // Closed, consistently oriented 2-manifold: every directed edge once, and its reverse once.
  std::unordered_map<uint64_t, int32_t> edge;  // directed edge -> 3 face + local edge
  edge.reserve(3 * static_cast<size_t>(m));
  auto key = [](int32_t a, int32_t b) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
  };
  for (int32_t f = 0; f < m; ++f) {
    const auto& t = r.tris_[f];
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= n)
        return InvalidArgument("triangle " + std::to_string(f) + " refers to node " +
                               std::to_string(t[k]) + ", outside [0, " + std::to_string(n) + ")");
    }
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0])
      return InvalidArgument("triangle " + std::to_string(f) + " repeats a node");
    for (int k = 0; k < 3; ++k) {
      const int32_t a = t[k], b = t[(k + 1) % 3];
      if (!edge.emplace(key(a, b), 3 * f + k).second)
        return InvalidArgument("edge (" + std::to_string(a) + ", " + std::to_string(b) +
                               ") of triangle " + std::to_string(f) +
                               " is used twice in the same direction: the surface is "
                               "non-manifold or inconsistently oriented");
    }
  }
  r.adj_.assign(m, {-1, -1, -1});
  double edge_sum = 0.0;
  for (int32_t f = 0; f < m; ++f) {
    const auto& t = r.tris_[f];
    for (int k = 0; k < 3; ++k) {
      const int32_t a = t[k], b = t[(k + 1) % 3];
      auto it = edge.find(key(b, a));
      if (it == edge.end())
        return InvalidArgument("edge (" + std::to_string(a) + ", " + std::to_string(b) +
                               ") of triangle " + std::to_string(f) +
                               " has no opposite triangle: the surface is not closed");
      r.adj_[f][k] = it->second / 3;
      edge_sum += (positions[a] - positions[b]).norm();
    }
  }
  r.vf_offset_.assign(n + 1, 0);
  for (const auto& t : r.tris_)
    for (int32_t v : t) ++r.vf_offset_[v + 1];
  for (int32_t i = 0; i < n; ++i) r.vf_offset_[i + 1] += r.vf_offset_[i];
  r.vf_faces_.assign(3 * static_cast<size_t>(m), 0);
  {
    std::vector<int32_t> fill(r.vf_offset_.begin(), r.vf_offset_.end() - 1);
    for (int32_t f = 0; f < m; ++f)
      for (int32_t v : r.tris_[f]) r.vf_faces_[fill[v]++] = f;
  }

  const double mean_edge = edge_sum / (3.0 * m);
  if (!(mean_edge > 0.0)) return InvalidArgument("surface has zero extent");
  const double cell = config.cell_size > 0.0 ? config.cell_size
                                             : std::max(2.0 * mean_edge, 0.5 * config.tool_radius);
  r.grid_.Build(r.tris_, positions, cell, 0.0);

  const DeviceLimits& d = config.device;
  r.k_stable_ = 2.0 * (d.damping - config.coupling_damping) / d.tick;
  r.k_ =
      std::min({config.coupling_stiffness, d.max_stiffness, config.stability_margin * r.k_stable_});

  r.candidates_.reserve(m);
  r.planes_.reserve(m);
  r.node_forces_.reserve(3 * kMaxContactFaces);

  // Start the proxy at the tool, pushed out of the surface if the tool starts inside it.
  r.proxy_ = tool;
  r.candidates_.resize(m);
  for (int32_t f = 0; f < m; ++f) r.candidates_[f] = f;
  if (!r.Depenetrate(positions, r.proxy_, std::numeric_limits<double>::infinity()))
    return InvalidArgument("cannot place the proxy outside the surface near the tool");
  r.candidates_.clear();
  return r;
}

Vec3 Renderer::FaceNormal(std::span<const Vec3> x, int32_t f) const {
  const auto& t = tris_[f];
  const Vec3 n = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
  const double len = n.norm();
  return len > 0.0 ? Vec3(n / len) : Vec3::Zero();
}

Vec3 Renderer::PseudoNormal(std::span<const Vec3> x, const Plane& pl) const {
  // Angle-weighted pseudo-normals (Baerentzen & Aanaes 2005) give the inside/outside sign.
  const Feature feature = static_cast<Feature>(pl.feature);
  const int32_t f = pl.face;
  switch (feature) {
    case Feature::kFace: return FaceNormal(x, f);
    case Feature::kEdge0:
    case Feature::kEdge1:
    case Feature::kEdge2: {
      const int k = static_cast<int>(feature) - static_cast<int>(Feature::kEdge0);
      return FaceNormal(x, f) + FaceNormal(x, adj_[f][k]);
    }
    default: {
      const int k = static_cast<int>(feature) - static_cast<int>(Feature::kVertex0);
      const int32_t v = tris_[f][k];
      Vec3 sum = Vec3::Zero();
      for (int32_t i = vf_offset_[v]; i < vf_offset_[v + 1]; ++i) {
        const int32_t g = vf_faces_[i];
        const auto& t = tris_[g];
        const int c = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
        const Vec3 e1 = x[t[(c + 1) % 3]] - x[v];
        const Vec3 e2 = x[t[(c + 2) % 3]] - x[v];
        const double l1 = e1.norm(), l2 = e2.norm();
        if (l1 <= 0.0 || l2 <= 0.0) continue;
        const double angle = std::acos(std::clamp(e1.dot(e2) / (l1 * l2), -1.0, 1.0));
        sum += angle * FaceNormal(x, g);
      }
      return sum;
    }
  }
}

int32_t Renderer::Evaluate(std::span<const Vec3> x, const Vec3& p, double prune_gap) {
  // Linearises every candidate at p; drops those that cannot be reached within prune_gap.
  const double r = config_.tool_radius;
  planes_.clear();
  int32_t closest = -1;
  double best = std::numeric_limits<double>::infinity();
  size_t kept = 0;
  for (int32_t f : candidates_) {
    const auto& t = tris_[f];
    const ClosestPoint cp = ClosestPointOnTriangle(p, x[t[0]], x[t[1]], x[t[2]]);
    const Vec3 d = p - cp.point;
    const double dist = d.norm();
    if (dist - r > prune_gap) continue;
    candidates_[kept++] = f;
    Plane pl;
    pl.face = f;
    pl.point = cp.point;
    pl.bary = cp.bary;
    pl.feature = static_cast<uint8_t>(cp.feature);
    pl.gap = dist - r;
    pl.n = dist > 0.0 ? Vec3(d / dist) : FaceNormal(x, f);
    pl.c = pl.n.dot(cp.point) + r;
    if (dist < best) {
      best = dist;
      closest = static_cast<int32_t>(planes_.size());
    }
    planes_.push_back(pl);
  }
  candidates_.resize(kept);
  return closest;
}

bool Renderer::Inside(std::span<const Vec3> x, const Vec3& p, int32_t closest) const {
  const Plane& pl = planes_[closest];
  return (p - pl.point).dot(PseudoNormal(x, pl)) < 0.0;
}

bool Renderer::Depenetrate(std::span<const Vec3> x, Vec3& p, double keep) {
  const double r = config_.tool_radius;
  for (int it = 0; it <= kMaxDepenetration; ++it) {
    const int32_t closest = Evaluate(x, p, keep);
    if (closest < 0) return true;
    if (Inside(x, p, closest)) {
      if (it == kMaxDepenetration) return false;
      const Plane& pl = planes_[closest];
      const Vec3 out = pl.point - p;
      const double len = out.norm();
      Vec3 dir = len > 1e-15 ? Vec3(out / len) : PseudoNormal(x, pl).normalized();
      p = pl.point + r * dir;
      continue;
    }
    int32_t worst = -1;
    for (int32_t i = 0; i < static_cast<int32_t>(planes_.size()); ++i) {
      if (planes_[i].gap < -kDepthTol && (worst < 0 || planes_[i].gap < planes_[worst].gap))
        worst = i;
    }
    if (worst < 0) return true;
    if (it == kMaxDepenetration) return false;
    const Plane& pl = planes_[worst];
    p = pl.point + r * pl.n;
  }
  return false;
}

int32_t Renderer::Touching(std::array<HalfSpace, kMaxContactFaces>& h, double gap_limit,
                           std::array<int32_t, kMaxContactFaces>* which, int32_t* nwhich) const {
  // Half-spaces for the projection: the touching planes (a proxy on a vertex touches every face
  // around it with one plane), then the planes of nearby faces that rise above a touching plane
  // (a concave crease the motion will reach: the projection lands in it at once instead of
  // bouncing between its sides). Planes of faces that fall away (convex) are left out: they
  // would hold the proxy above a rounded edge. `which` lists the touching faces, nearest first.
  std::array<double, kMaxContactFaces> hgap;
  int32_t nh = 0, nw = 0;
  auto add = [&](const Plane& pl) {
    for (int32_t j = 0; j < nh; ++j) {
      if (h[j].n.dot(pl.n) > 1.0 - 1e-9) {
        h[j].c = std::max(h[j].c, pl.c);
        hgap[j] = std::min(hgap[j], pl.gap);
        return;
      }
    }
    if (nh < kMaxContactFaces) {
      h[nh] = {pl.n, pl.c};
      hgap[nh++] = pl.gap;
      return;
    }
    int32_t far = 0;
    for (int32_t j = 1; j < nh; ++j)
      if (hgap[j] > hgap[far]) far = j;
    if (pl.gap < hgap[far]) {
      h[far] = {pl.n, pl.c};
      hgap[far] = pl.gap;
    }
  };
  for (int32_t i = 0; i < static_cast<int32_t>(planes_.size()); ++i) {
    const Plane& pl = planes_[i];
    if (pl.gap > kTouch) continue;
    if (which != nullptr) {
      if (nw < kMaxContactFaces) {
        (*which)[nw++] = i;
      } else {
        int32_t far = 0;
        for (int32_t j = 1; j < nw; ++j)
          if (planes_[(*which)[j]].gap > planes_[(*which)[far]].gap) far = j;
        if (pl.gap < planes_[(*which)[far]].gap) (*which)[far] = i;
      }
    }
    add(pl);
  }
  const int32_t touching = nh;
  if (touching > 0 && gap_limit > kTouch) {
    for (const Plane& pl : planes_) {
      if (pl.gap <= kTouch || pl.gap > gap_limit) continue;
      if (pl.feature != static_cast<uint8_t>(Feature::kFace)) continue;
      bool concave = false;
      for (int32_t j = 0; j < touching && !concave; ++j) {
        // Above touching plane j by more than the proxy's own clearance: the face rises.
        concave = h[j].n.dot(pl.point) + config_.tool_radius > h[j].c + 1e-9;
      }
      if (concave) add(pl);
    }
  }
  if (which != nullptr) {
    std::sort(which->begin(), which->begin() + nw,
              [this](int32_t a, int32_t b) { return planes_[a].gap < planes_[b].gap; });
  }
  if (nwhich != nullptr) *nwhich = nw;
  return nh;
}

Vec3 Renderer::MoveProxy(std::span<const Vec3> x, const Vec3& from, const Vec3& target,
                         const Vec3& device, bool* touched) {
  // Constraint-based god-object step: project the target onto the touching half-spaces, then
  // advance towards it as far as every near face's half-space allows. The half-spaces support
  // the convex sets face + ball, so every point reached is at least tool_radius from each face.
  const double keep = kSettle * config_.tool_radius;
  Vec3 p = from;
  double left = config_.max_step;
  std::array<HalfSpace, kMaxContactFaces> h;
  auto touching = [&] {
    bool any = false;
    for (const Plane& pl : planes_) any = any || pl.gap <= kTouch;
    return any;
  };
  bool held = false;  // the last advance was held back by the surface
  auto advance = [&](Vec3 d, double& budget) {
    // Re-linearise at least every half radius so that slides follow a curved surface.
    double len = d.norm();
    const double cap = std::min(budget, kRelinearise * config_.tool_radius);
    if (len > cap) {
      d *= cap / len;
      len = cap;
    }
    double s = 1.0;
    for (const Plane& pl : planes_) {
      const double nd = pl.n.dot(d);
      if (nd < -1e-11) s = std::min(s, std::max(pl.gap, 0.0) / -nd);
    }
    p += s * d;
    budget -= s * len;
    Evaluate(x, p, std::max(left, keep) + kTouch);
    held = held || s < 1.0;
    return s * len;
  };
  for (int it = 0; it < kMaxMoves && left > kMinMove; ++it) {
    const int32_t nh = Touching(h, left, nullptr, nullptr);
    Vec3 y;
    if (!internal::ProjectOntoHalfSpaces(target, std::span(h.data(), nh), kProjTol, y)) break;
    if ((y - p).norm() < kMinMove) break;
    held = (y - target).norm() > kMinMove;
    if (advance(y - p, left) < kMinMove) break;
  }
  // Settle: a slide along linearised planes of a curved surface (or one cut short by max_step)
  // can end just above it; close that gap along the line to the device, by at most `keep`.
  double settle = keep;
  for (int it = 0; it < 4 && settle > kMinMove; ++it) {
    if (touching() || (device - p).norm() < kMinMove) break;
    if (advance(device - p, settle) < kMinMove) break;
  }
  *touched = held || touching();
  return p;
}

void Renderer::DistributeReaction(std::span<const Vec3> x, const Vec3& object_force) {
  // Barycentric split over the contact faces: the node forces sum to object_force and have the
  // same moment as object_force applied at the contact points.
  (void)x;
  node_forces_.clear();
  if (anchor_count_ == 0 || object_force.isZero(0.0)) return;
  const double share = 1.0 / anchor_count_;
  for (int32_t a = 0; a < anchor_count_; ++a) {
    const auto& t = tris_[anchors_[a].face];
    for (int k = 0; k < 3; ++k) {
      const double w = share * anchors_[a].bary[k];
      if (w == 0.0) continue;
      auto it = std::find_if(node_forces_.begin(), node_forces_.end(),
                             [&](const NodeForce& nf) { return nf.node == t[k]; });
      if (it == node_forces_.end()) {
        node_forces_.push_back({t[k], w * object_force});
      } else {
        it->force += w * object_force;
      }
    }
  }
}

Result<ContactOutput> Renderer::Update(const DeviceState& device, std::span<const Vec3> x,
                                       double dt) {
  if (static_cast<int32_t>(x.size()) != node_count_)
    return InvalidArgument("Update got " + std::to_string(x.size()) +
                           " node positions; the "
                           "renderer was built for " +
                           std::to_string(node_count_));
  if (!(dt > 0.0 && dt <= 0.1))
    return InvalidArgument("Update dt = " + Num(dt) + " s is outside (0, 0.1]");
  if (!Finite(device.position) || !Finite(device.velocity))
    return InvalidArgument("device position or velocity is not finite");

  const double r = config_.tool_radius;
  time_ += dt;
  grid_.Rebin(tris_, x, config_.rebin_faces_per_tick, time_);

  // 1. Carry the proxy with the surface it rests on.
  Vec3 p = proxy_;
  if (anchored_) {
    const auto& t = tris_[anchors_[0].face];
    const Vec3& b = anchors_[0].bary;
    p = b[0] * x[t[0]] + b[1] * x[t[1]] + b[2] * x[t[2]] + anchor_offset_;
  }

  // 2. Faces that the proxy may reach this tick, from the grid, widened by how far any face can
  //    have moved since it was binned.
  const double stale = config_.max_surface_speed * grid_.staleness(time_);
  const double reach = (2.0 + kSettle) * r + config_.max_step + grid_.reach_bound() + stale;
  candidates_.clear();
  grid_.Query(p, reach, candidates_);
  const int32_t queried = static_cast<int32_t>(candidates_.size());

  // 3. Push the proxy out of the surface if the surface moved into it. The query covers a push
  //    of up to tool_radius; after a larger one (the surface swept over the proxy), search again
  //    around the pushed proxy.
  const double all = std::numeric_limits<double>::infinity();
  Vec3 center = p;
  Depenetrate(x, p, all);
  for (int k = 0; k < 2 && (p - center).norm() > r; ++k) {
    center = p;
    candidates_.clear();
    grid_.Query(p, reach, candidates_);
    Depenetrate(x, p, all);
  }
  Evaluate(x, p, config_.max_step + kSettle * r + kTouch);

  // 4. Friction cone (Melder & Harwin): the proxy sticks while the device stays within the cone
  //    around the frictionless proxy; otherwise it slides to the cone's edge.
  const Vec3 g = device.position;
  Vec3 target = g;
  bool sliding = false;
  {
    std::array<HalfSpace, kMaxContactFaces> h;
    const bool touching = Touching(h, kTouch, nullptr, nullptr) > 0;
    const int32_t nh = touching ? Touching(h, config_.max_step, nullptr, nullptr) : 0;
    Vec3 free_proxy;
    if (nh > 0 &&
        internal::ProjectOntoHalfSpaces(g, std::span(h.data(), nh), kProjTol, free_proxy)) {
      const double depth = (g - free_proxy).norm();
      if (depth > kMinMove) {
        const Vec3 off = p - free_proxy;
        const double lateral = off.norm();
        const double mu = stuck_ ? config_.static_friction : config_.dynamic_friction;
        if (lateral <= mu * depth) {
          target = p;
          stuck_ = true;
        } else {
          target = free_proxy + off * (config_.dynamic_friction * depth / lateral);
          stuck_ = false;
          sliding = true;
        }
        // Aim a little below the linearised planes, towards the device: where the true surface
        // curves away from them (edges, vertices) the proxy then still lands on it.
        target += (g - free_proxy) * (std::min(depth, 0.1 * r) / depth);
      } else {
        stuck_ = false;
      }
    } else {
      stuck_ = false;
    }
  }

  // 5. Move the proxy towards the target under the non-penetration constraints.
  bool touched = false;
  p = MoveProxy(x, p, target, g, &touched);

  // 6. Contact set at the final proxy. A proxy that touched the surface this tick but ran out of
  //    max_step while sliding may end just above it: it stays in contact, its reaction on the
  //    last contact faces.
  std::array<HalfSpace, kMaxContactFaces> h;
  std::array<int32_t, kMaxContactFaces> which;
  int32_t touching = 0;
  Touching(h, kTouch, &which, &touching);
  const bool held = (g - p).norm() > kMinMove;
  // The friction cone or the touching planes moved the target off the device: the surface
  // holds the proxy back even if the slide ended above it.
  const bool aimed = (target - g).norm() > kMinMove;
  const bool in_contact = held && (touching > 0 || ((touched || aimed) && anchor_count_ > 0));
  Vec3 normal = Vec3::Zero();
  if (in_contact && touching > 0) {
    for (int32_t i = 0; i < touching; ++i) normal += planes_[which[i]].n;
    normal.normalize();
    anchor_count_ = touching;
    for (int32_t i = 0; i < touching; ++i)
      anchors_[i] = {planes_[which[i]].face, planes_[which[i]].bary};
    anchor_offset_ = p - planes_[which[0]].point;
  } else if (in_contact) {
    normal = (p - g).normalized();
  }
  anchored_ = in_contact && touching > 0;

  // 7. Virtual coupling, unilateral, then the device's force and force-rate limits.
  Vec3 force = Vec3::Zero();
  if (in_contact) {
    const Vec3 v_proxy = (p - proxy_) / dt;
    force = k_ * (p - g) + config_.coupling_damping * (v_proxy - device.velocity);
    if (force.dot(normal) <= 0.0) force.setZero();
  }
  const DeviceLimits& lim = config_.device;
  const double mag = force.norm();
  if (mag > lim.max_force) force *= lim.max_force / mag;
  const Vec3 delta = force - force_;
  const double max_delta = lim.max_force_rate * dt;
  const double dn = delta.norm();
  if (dn > max_delta * (1.0 + 1e-9)) force = force_ + delta * (max_delta / dn);
  force_ = force;
  proxy_ = p;

  // 8. Equal and opposite reaction on the contact nodes (the last contact while ramping down).
  DistributeReaction(x, -force);
  if (!in_contact && force.isZero(0.0)) anchor_count_ = 0;

  ContactOutput out;
  out.wrench.force = force;
  out.node_forces = std::span<const NodeForce>(node_forces_.data(), node_forces_.size());
  out.proxy = p;
  out.contact_normal = normal;
  out.in_contact = in_contact;
  out.sliding = sliding;
  out.contact_faces = touching;
  out.candidate_faces = queried;
  return out;
}

}  // namespace rheo::haptics
