#include "daemon/device/tool_contact.h"

#include <algorithm>

namespace rheo::daemon {

double MinSurfaceMass(std::span<const std::array<int32_t, 3>> surface,
                      std::span<const double> masses) {
  double min_mass = 0.0;
  for (const auto& f : surface)
    for (int32_t v : f)
      if (v >= 0 && static_cast<size_t>(v) < masses.size() &&
          (min_mass == 0.0 || masses[v] < min_mass))
        min_mass = masses[v];
  return min_mass;
}

Result<std::unique_ptr<ObjectContact>> MakeRendererContact(
    const haptics::RendererConfig& config, std::span<const std::array<int32_t, 3>> surface,
    std::span<const Vec3> positions, const Vec3& tool, double min_mass) {
  haptics::RendererConfig rc = config;
  if (min_mass > 0.0)
    rc.coupling_stiffness =
        std::clamp(2.0 * min_mass / (rc.device.tick * rc.device.tick), 1.0, rc.coupling_stiffness);
  auto r = haptics::Renderer::Create(rc, surface, positions, tool);
  if (!r.ok()) return r.error();
  return std::unique_ptr<ObjectContact>(new RendererContact(std::move(r).value()));
}

void ToolContact::Forget(const EngineSlot& slot) {
  if (slot.object == object_ && slot.multirate == multirate_) {
    object_ = nullptr;
    multirate_ = nullptr;
    forced_count_ = 0;
  }
}

void ToolContact::Release() {
  if (multirate_) multirate_->ClearLoads();
  if (object_)
    for (int i = 0; i < forced_count_; ++i)
      object_->SetExternalForce(forced_nodes_[i], Vec3::Zero());
  forced_count_ = 0;
}

ContactTick ToolContact::Update(std::span<EngineSlot> slots, const Vec3& position,
                                const Vec3& velocity, double dt, bool object_feels) {
  ContactTick out;
  out.proxy = position;
  // The tool renders against the first object that has a renderer.
  EngineSlot* target = nullptr;
  for (EngineSlot& s : slots)
    if (s.contact) {
      target = &s;
      break;
    }
  if (!target || target->object != object_ || target->multirate != multirate_) {
    Release();
    object_ = target ? target->object : nullptr;
    multirate_ = target ? target->multirate : nullptr;
  }
  if (!target) return out;
  out.instance_id = target->instance_id;
  auto& r = static_cast<RendererContact*>(target->contact)->renderer;
  out.stiffness = r.effective_stiffness();
  auto o = r.Update({position, velocity}, target->positions(), dt);
  if (!o.ok()) {
    out.renderer_error = true;
    Release();
    return out;
  }
  out.force = o->wrench.force;
  out.torque = o->wrench.torque;
  out.proxy = o->proxy;
  out.in_contact = o->in_contact;
  Release();
  // The object feels the tool only while the device displays its reaction.
  if (object_feels) {
    if (MultiRateObject* mr = target->multirate) {
      // The whole's step takes many ticks' loads at once: each goes with its share of the
      // coupling's stiffness, so that the whole's implicit step holds the coupling as the spring
      // it is (sim/multirate.h, ForceWindow::ApplyAverage).
      double norm_sum = 0.0;
      for (const haptics::NodeForce& nf : o->node_forces) norm_sum += nf.force.norm();
      for (const haptics::NodeForce& nf : o->node_forces) {
        const double k = norm_sum > 0.0 ? out.stiffness * nf.force.norm() / norm_sum : 0.0;
        if (!mr->AddLoad({nf.node, nf.force, k})) break;
        out.object_force += nf.force;
      }
    } else {
      for (const haptics::NodeForce& nf : o->node_forces) {
        if (forced_count_ >= static_cast<int>(forced_nodes_.size())) break;
        target->object->SetExternalForce(nf.node, nf.force);
        forced_nodes_[forced_count_++] = nf.node;
        out.object_force += nf.force;
      }
    }
  }
  if (MultiRateObject* mr = target->multirate) mr->SetFocus(out.proxy);
  return out;
}

}  // namespace rheo::daemon
