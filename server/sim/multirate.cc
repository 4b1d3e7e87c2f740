#include "sim/multirate.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace rheo::sim {

Status CheckPatchOptions(const PatchOptions& options) {
  if (!(options.radius > 0.0 && options.radius <= 1.0)) {
    return InvalidArgument("patch radius " + std::to_string(options.radius) +
                           " m is outside (0, 1]");
  }
  if (!(options.tick > 0.0 && options.tick <= 0.1)) {
    return InvalidArgument("patch tick " + std::to_string(options.tick) + " s is outside (0, 0.1]");
  }
  if (!(options.whole_substep > 0.0 && options.whole_substep <= 0.1)) {
    return InvalidArgument("whole substep " + std::to_string(options.whole_substep) +
                           " s is outside (0, 0.1]");
  }
  if (options.max_inner_nodes < 0) {
    return InvalidArgument("patch max_inner_nodes " + std::to_string(options.max_inner_nodes) +
                           " is negative");
  }
  return {};
}

Result<Patch> Patch::Build(const SimObject& whole, const Vec3& center, const PatchOptions& options,
                           const Parameters* patch_params) {
  if (Status s = CheckPatchOptions(options); !s.ok()) return s.error();
  const Model& wm = whole.model();
  const State& ws = whole.state();
  const int32_t n = wm.num_nodes;
  double r2 = options.radius * options.radius;
  if (options.max_inner_nodes > 0) {
    std::vector<double> d2;
    for (int32_t i = 0; i < n; ++i) {
      const double q = (ws.x[i] - center).squaredNorm();
      if (!wm.fixed[i] && q <= r2) d2.push_back(q);
    }
    const size_t cap = static_cast<size_t>(options.max_inner_nodes);
    if (d2.size() > cap) {
      std::nth_element(d2.begin(), d2.begin() + (cap - 1), d2.end());
      r2 = d2[cap - 1];
    }
  }
  Patch p;
  p.center_ = center;
  p.radius_ = std::sqrt(r2);
  p.local_.assign(n, -1);
  for (int32_t i = 0; i < n; ++i) {
    if (wm.fixed[i] || (ws.x[i] - center).squaredNorm() > r2) continue;
    p.local_[i] = static_cast<int32_t>(p.global_.size());
    p.global_.push_back(i);
  }
  p.inner_ = static_cast<int32_t>(p.global_.size());
  if (p.inner_ == 0) {
    return InvalidArgument("no free node of the object lies within " +
                           std::to_string(options.radius) + " m of the patch centre");
  }
  // Every tetrahedron at an inner node, and the boundary nodes they bring.
  std::vector<std::array<int32_t, 4>> tets;
  for (const auto& t : wm.tets) {
    if (!std::any_of(t.begin(), t.end(), [&](int32_t v) { return p.IsInner(v); })) continue;
    std::array<int32_t, 4> lt;
    for (int q = 0; q < 4; ++q) {
      if (p.local_[t[q]] < 0) {
        p.local_[t[q]] = static_cast<int32_t>(p.global_.size());
        p.global_.push_back(t[q]);
      }
      lt[q] = p.local_[t[q]];
    }
    tets.push_back(lt);
  }
  const int32_t pn = static_cast<int32_t>(p.global_.size());
  // Edges with both ends in the patch (sorted by first node, as BuildModel's are), each with the
  // whole's edge it copies its state from; surface faces at an inner node.
  struct LocalEdge {
    std::array<int32_t, 2> ends;
    size_t whole;
  };
  std::vector<LocalEdge> edges;
  for (size_t k = 0; k < wm.edges.size(); ++k) {
    int32_t a = p.local_[wm.edges[k][0]], b = p.local_[wm.edges[k][1]];
    if (a < 0 || b < 0 || (a >= p.inner_ && b >= p.inner_)) continue;
    if (a > b) std::swap(a, b);
    edges.push_back({{a, b}, k});
  }
  std::sort(edges.begin(), edges.end(),
            [](const LocalEdge& x, const LocalEdge& y) { return x.ends < y.ends; });
  std::vector<std::array<int32_t, 2>> edge_ends(edges.size());
  for (size_t k = 0; k < edges.size(); ++k) edge_ends[k] = edges[k].ends;
  std::vector<std::array<int32_t, 3>> faces;
  for (const auto& f : wm.faces) {
    const int32_t a = p.local_[f[0]], b = p.local_[f[1]], c = p.local_[f[2]];
    if (a < 0 || b < 0 || c < 0) continue;
    if (a >= p.inner_ && b >= p.inner_ && c >= p.inner_) continue;
    faces.push_back({a, b, c});
  }
  std::vector<Vec3> rest(pn);
  std::vector<double> mass(pn);
  for (int32_t l = 0; l < pn; ++l) {
    rest[l] = wm.rest_positions[p.global_[l]];
    mass[l] = wm.mass[p.global_[l]];
  }
  Result<Model> model = BuildModelFromParts(rest, mass, edge_ends, faces, tets);
  if (!model.ok()) return model.error();
  for (int32_t l = p.inner_; l < pn; ++l) {
    model->fixed[l] = 1;
    model->inv_mass[l] = 0.0;
  }
  // The boundary's edges are not the patch's, so its elements' pairs of boundary nodes are no
  // edges: indexed again with the boundary fixed, the patch's product uses the assembled blocks
  // instead of a pass over its elements per CG iteration (TetJacobian: 20 % of the loop's time
  // in the daemon's 92.6k-tet press).
  IndexElementsByEdge(*model);
  // The global volume condition (eq. 4) acts through the whole's volume: the patch's faces
  // enclose part of it, State::volume_offset (set by Follow) the rest, so the condition stays in
  // the patch's implicit system with the dent the patch makes.
  model->rest_volume = wm.rest_volume;
  const Parameters params = patch_params ? *patch_params : whole.parameters();
  Result<std::unique_ptr<SimObject>> obj =
      SimObject::Create(std::move(*model), params, whole.integrator());
  if (!obj.ok()) return obj.error();
  p.object_ = std::move(*obj);
  State& s = p.object_->state_;
  for (int32_t l = 0; l < pn; ++l) {
    s.x[l] = ws.x[p.global_[l]];
    s.v[l] = ws.v[p.global_[l]];
  }
  for (size_t k = 0; k < edges.size(); ++k) {
    s.a[k] = ws.a[edges[k].whole];
    s.tension[k] = ws.tension[edges[k].whole];
  }
  // The integrator's history, so that the patch's first substeps are those the whole would take
  // (a restart from BDF1 differs from BDF2 by about h^2 a / 3 in one substep: a dent's worth under
  // a tool load). The whole's own history when it steps at the patch's substep; else one made
  // for a constant velocity over the last substep.
  const double h = options.tick / SimObject::ImplicitSubsteps(params, options.tick);
  const bool same_h = ws.have_prev && std::abs(ws.prev_h - h) <= 1e-12 * h;
  for (int32_t l = 0; l < pn; ++l) {
    const int32_t g = p.global_[l];
    s.x_prev[l] = same_h ? ws.x_prev[g] : Vec3(s.x[l] - h * s.v[l]);
    s.v_prev[l] = same_h ? ws.v_prev[g] : s.v[l];
    s.dv[l] = same_h ? ws.dv[g] : Vec3::Zero();
    s.dv_prev[l] = same_h ? ws.dv_prev[g] : Vec3::Zero();
    s.f_shape_prev[l] = ws.f_shape_prev[g];
  }
  s.have_prev = true;
  s.prev_h = h;
  s.have_prev_shape = same_h && ws.have_prev_shape;
  p.object_->SaveGood();
  p.tool_.assign(p.inner_, 0);
  p.tool_nodes_.reserve(p.inner_);
  p.Follow(whole);
  return p;
}

namespace {
// Six times the volume the faces `faces` enclose with the origin, at positions x[map[node]].
template <typename Map>
double SixVolume(std::span<const std::array<int32_t, 3>> faces, std::span<const Vec3> x, Map map) {
  double v = 0.0;
  for (const auto& f : faces) v += x[map(f[0])].dot(x[map(f[1])].cross(x[map(f[2])]));
  return v;
}
}  // namespace

void Patch::Follow(const SimObject& whole, bool inner_nodes_too) {
  const State& ws = whole.state();
  State& s = object_->state_;
  const int32_t pn = static_cast<int32_t>(global_.size());
  const double h = s.have_prev ? s.prev_h : 0.0;
  double moved2 = 0.0;
  for (int32_t l = inner_nodes_too ? 0 : inner_; l < pn; ++l) {
    const Vec3& x = ws.x[global_[l]];
    const Vec3& v = ws.v[global_[l]];
    moved2 = std::max(moved2, (x - s.x[l]).squaredNorm() + v.squaredNorm());
    s.x[l] = x;
    s.v[l] = v;
    // The BDF2 history of a held node: one substep back on the same line, so that the next
    // substep moves it by h v.
    s.x_prev[l] = x - h * v;
    s.v_prev[l] = v;
    if (l < inner_) {
      s.dv[l].setZero();
      s.dv_prev[l].setZero();
    }
  }
  if (inner_nodes_too) s.have_prev_shape = false;
  // The whole's volume with the patch's faces where the patch has them: the patch's faces at the
  // whole's positions are taken out, so that its own (at its inner nodes' positions) count.
  const Parameters& wp = whole.parameters();
  if (wp.volume_k > 0.0 || wp.volume_c > 0.0) {
    const auto faces = std::span<const std::array<int32_t, 3>>(object_->model().faces);
    const double whole6 = SixVolume(whole.model().faces, ws.x, [](int32_t i) { return i; });
    const double part6 = SixVolume(faces, ws.x, [&](int32_t l) { return global_[l]; });
    s.volume_offset = (whole6 - part6) / 6.0;
  }
  if (moved2 > 0.0) object_->Wake();
}

void Patch::HoldBoundary() {
  State& s = object_->state_;
  const int32_t pn = static_cast<int32_t>(global_.size());
  for (int32_t l = inner_; l < pn; ++l) {
    s.v[l].setZero();
    s.x_prev[l] = s.x[l];
    s.v_prev[l].setZero();
  }
}

bool Patch::SetToolForce(int32_t whole_node, const Vec3& force, double stiffness) {
  if (!IsInner(whole_node) || !force.allFinite() || !(stiffness >= 0.0)) return false;
  const int32_t l = local_[whole_node];
  if (!object_->SetExternalForce(l, force, stiffness)) return false;
  if (!tool_[l]) tool_nodes_.push_back(l);  // capacity: every inner node
  tool_[l] = 1;
  return true;
}

void Patch::ClearToolForces() {
  for (int32_t l : tool_nodes_) {
    tool_[l] = 0;
    object_->SetExternalForce(l, Vec3::Zero());
  }
  tool_nodes_.clear();
}

void Patch::Overlay(std::span<Vec3> whole_positions) const {
  const auto x = object_->positions();
  for (int32_t l = 0; l < inner_; ++l) whole_positions[global_[l]] = x[l];
}

ForceWindow::ForceWindow(int32_t capacity)
    : slot_(2 * static_cast<size_t>(std::max(capacity, 1)), -1),
      used_(static_cast<size_t>(std::max(capacity, 1))) {}

bool ForceWindow::Add(int32_t node, const Vec3& force, double dt, double stiffness,
                      const Vec3& at) {
  const size_t mask_size = slot_.size();
  size_t h = (static_cast<uint32_t>(node) * 2654435761u) % mask_size;
  for (size_t probe = 0; probe < mask_size; ++probe, h = (h + 1) % mask_size) {
    const int32_t e = slot_[h];
    if (e >= 0 && used_[e].node == node) {
      used_[e].impulse += force * dt;
      used_[e].k_dt += stiffness * dt;
      used_[e].kx_dt += (stiffness * dt) * at;
      return true;
    }
    if (e < 0) {
      if (used_count_ == used_.size()) break;
      slot_[h] = static_cast<int32_t>(used_count_);
      used_[used_count_++] = Entry{node, force * dt, stiffness * dt, (stiffness * dt) * at};
      return true;
    }
  }
  ++overflowed_;
  return false;
}

void ForceWindow::ApplyAverage(SimObject& whole) const {
  whole.ClearExternalForces();
  if (!(duration_ > 0.0)) return;
  const auto x = whole.positions();
  for (size_t k = 0; k < used_count_; ++k) {
    const Entry& e = used_[k];
    // The window's average of F_t - k_t (x - x_t), a spring the whole's implicit step takes in.
    const double k_avg = e.k_dt / duration_;
    const Vec3 f = (e.impulse + e.kx_dt) / duration_ - k_avg * x[e.node];
    whole.SetExternalForce(e.node, f, k_avg);
  }
}

void ForceWindow::Clear() {
  std::fill(slot_.begin(), slot_.end(), -1);
  used_count_ = 0;
  duration_ = 0.0;
  overflowed_ = 0;
}

Result<MultiRate> MultiRate::Create(std::unique_ptr<SimObject> whole, int32_t period,
                                    const PatchOptions& options) {
  if (!whole) return InvalidArgument("no object to step");
  if (period < 1 || period > 1000) {
    return InvalidArgument("multi-rate period of " + std::to_string(period) +
                           " ticks is outside [1, 1000]");
  }
  // Checked here too: Sync() builds patches later and keeps the old one when a build fails.
  if (Status s = CheckPatchOptions(options); !s.ok()) return s.error();
  MultiRate mr;
  mr.whole_ = std::move(whole);
  mr.period_ = period;
  mr.options_ = options;
  if (Status s = mr.SetParameters(mr.whole_->parameters()); !s.ok()) return s.error();
  const auto x = mr.whole_->positions();
  mr.render_.assign(x.begin(), x.end());
  return mr;
}

Parameters MultiRate::WholeParameters(const Parameters& given, int32_t period,
                                      const PatchOptions& options) {
  // The whole's step covers `period` ticks in substeps of at most whole_substep.
  const double step = period * options.tick;
  Parameters p = given;
  const int32_t per_tick = SimObject::ImplicitSubsteps(p, options.tick);
  const double substeps =
      std::max<double>(per_tick, std::ceil(step / options.whole_substep - 1e-9));
  p.implicit_substeps = std::min(substeps, 1000.0);
  return p;
}

Status MultiRate::SetParameters(Parameters given) {
  // By value: `given` may be the whole's own parameters (Create passes them), which the whole's
  // SetParameters below changes. Taken by reference, the patches got the whole's substeps (10 a
  // tick at a 10-tick period in the daemon's 92k-tet press: 485-504 us a tick, 35 us predicted).
  const Parameters p = WholeParameters(given, period_, options_);
  if (Status s = whole_->SetParameters(p); !s.ok()) return s;
  patch_params_ = std::move(given);
  whole_substeps_ = static_cast<int32_t>(p.implicit_substeps);
  return {};
}

int32_t MultiRate::RefineWholeSubsteps(int32_t max_substeps) {
  const int32_t next = std::min({2 * whole_substeps_, max_substeps, 1000});
  if (next <= whole_substeps_) return whole_substeps_;
  if (whole_->SetParameter("implicit_substeps", next).ok()) whole_substeps_ = next;
  return whole_substeps_;
}

bool MultiRate::WantsPatch(const Vec3& focus) const {
  return !patch_ || (focus - patch_->center()).norm() > 0.5 * patch_->radius();
}

Result<Patch> MultiRate::BuildPatch(const Vec3& focus) const {
  return Patch::Build(*whole_, focus, options_, &patch_params_);
}

void MultiRate::Sync(const Vec3& focus) {
  std::optional<Patch> fresh;
  bool replace = false;
  if (WantsPatch(focus)) {
    Result<Patch> p = BuildPatch(focus);
    // No node near the focus: the old patch (or none) stays; the tool is not touching.
    if (p.ok()) {
      fresh = std::move(*p);
      replace = true;
    }
  }
  Sync(fresh, replace);
}

void MultiRate::Sync(std::optional<Patch>& exchange, bool replace, bool refresh) {
  ++counts_.syncs;
  if (replace) {
    if (exchange) ++counts_.rebuilds;
    patch_.swap(exchange);
  } else if (patch_) {
    patch_->Follow(*whole_, refresh);
  }
  const auto x = whole_->positions();
  std::copy(x.begin(), x.end(), render_.begin());
  if (patch_) patch_->Overlay(render_);
  std::swap(filling_, closed_);
  filling_.Clear();
  counts_.window_overflow += closed_.overflowed();
}

StepResult MultiRate::StepWhole(double dt) {
  closed_.ApplyAverage(*whole_);
  if (!(dt > 0.0)) return StepResult{};
  return whole_->Step(dt);
}

StepResult MultiRate::FastTick(std::span<const NodeLoad> loads, double dt) {
  ++counts_.ticks;
  if (patch_) patch_->ClearToolForces();
  for (const NodeLoad& l : loads) {
    if (l.node < 0 || l.node >= static_cast<int32_t>(render_.size())) {
      ++counts_.outside_loads;
      continue;
    }
    filling_.Add(l.node, l.force, dt, l.stiffness, render_[l.node]);
    if (!patch_ || !patch_->SetToolForce(l.node, l.force, l.stiffness)) ++counts_.outside_loads;
  }
  filling_.AddDuration(dt);
  if (!patch_) return StepResult{};
  const StepResult r = patch_->Step(dt);
  counts_.patch_restores += r.restored;
  patch_->Overlay(render_);
  return r;
}

StepResult MultiRate::Tick(std::span<const NodeLoad> loads, const Vec3& focus, double dt) {
  if (counts_.ticks % period_ == 0) {
    Sync(focus);
    StepWhole(period_ * dt);
  }
  return FastTick(loads, dt);
}

}  // namespace rheo::sim
