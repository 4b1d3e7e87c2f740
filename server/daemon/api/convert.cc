#include "daemon/api/convert.h"

#include <sstream>

#include "daemon/record/recorder.h"
#include "mesh/mesh.h"
#include "sketch/sketch.h"

namespace rheo::daemon {

void SetVec(const std::array<double, 3>& a, v1::Vec3* out) {
  out->set_x(a[0]);
  out->set_y(a[1]);
  out->set_z(a[2]);
}

void SetVec(const Vec3& a, v1::Vec3* out) {
  out->set_x(a.x());
  out->set_y(a.y());
  out->set_z(a.z());
}

Vec3 ToVec(const std::array<double, 3>& a) {
  return Vec3(a[0], a[1], a[2]);
}

void SetQuaternion(const std::array<double, 4>& q, v1::Quat* out) {
  out->set_w(q[0]);
  out->set_x(q[1]);
  out->set_y(q[2]);
  out->set_z(q[3]);
}

v1::Integrator ToProto(sim::Integrator i) {
  return i == sim::Integrator::kImplicitEuler ? v1::INTEGRATOR_IMPLICIT
                                              : v1::INTEGRATOR_SYMPLECTIC_EULER;
}

void FillParameters(const sim::Parameters& p,
                    google::protobuf::RepeatedPtrField<v1::Parameter>* out) {
  for (const sim::ParameterInfo& info : sim::ParameterTable()) {
    v1::Parameter* q = out->Add();
    q->set_name(info.name);
    q->set_value(p.*(info.field));
    q->set_unit(info.unit);
    q->set_min(info.min);
    q->set_max(info.max);
    q->set_description(info.description);
  }
}

void FillSceneObject(const SceneEntry& e, bool sleeping, bool unstable, v1::SceneObject* out) {
  out->set_instance_id(e.instance_id);
  out->set_object_id(e.object_id);
  out->set_preset(e.preset);
  out->set_integrator(ToProto(e.integrator));
  FillParameters(e.params, out->mutable_parameters());
  SetVec(e.position, out->mutable_position());
  out->set_sleeping(sleeping);
  out->set_unstable(unstable);
  out->set_predicted_tick_us(e.cost.ns * 1e-3);
  if (e.multirate) {
    // Under the scene's mutation mutex (the object is not removed meanwhile).
    const MultiRateStats st = e.multirate->stats();
    v1::MultiRate* m = out->mutable_multi_rate();
    m->set_period_ticks(static_cast<uint32_t>(e.multirate_period));
    m->set_predicted_whole_step_ms(e.whole_cost.ns * 1e-6);
    m->set_patch_inner_nodes(static_cast<uint32_t>(st.patch_inner_nodes));
    m->set_patch_tets(static_cast<uint32_t>(st.patch_tets));
    m->set_syncs(st.syncs);
    m->set_late_ticks(st.late_ticks);
    m->set_whole_step_ms(static_cast<double>(st.whole_step_ns) * 1e-6);
    m->set_whole_step_max_ms(static_cast<double>(st.whole_step_max_ns) * 1e-6);
    m->set_whole_window_ms(st.whole_window_s * 1e3);
    m->set_patch_rebuilds(st.rebuilds);
    m->set_whole_restores(st.whole_restores);
    m->set_whole_lag_ms(st.whole_lag_s * 1e3);
    m->set_whole_substeps(static_cast<uint32_t>(st.whole_substeps));
  }
}

void FillPercentiles(const rt::Histogram& h, v1::Percentiles* out) {
  out->set_p50_us(h.Quantile(0.5) / 1e3);
  out->set_p99_us(h.Quantile(0.99) / 1e3);
  out->set_p999_us(h.Quantile(0.999) / 1e3);
  out->set_max_us(h.max_ns() / 1e3);
  out->set_mean_us(h.mean_ns() / 1e3);
  out->set_count(h.count());
}

std::vector<std::string> DeviceFaultList(const ToolTelemetry& t) {
  std::vector<std::string> out;
  if (t.emergency_stopped) out.push_back("emergency stop engaged");
  if (t.watchdog_tripped) out.push_back("watchdog tripped (the loop stalled)");
  std::stringstream names(drivers::FaultNames(t.faults));
  std::string item;
  while (std::getline(names, item, ',')) {
    size_t a = item.find_first_not_of(' ');
    if (a != std::string::npos) out.push_back(item.substr(a));
  }
  return out;
}

void FillToolState(const ToolTelemetry& t, const std::string& lease_holder, v1::ToolState* out) {
  out->set_present(true);
  SetVec(t.device_position, out->mutable_device_pose()->mutable_position());
  SetQuaternion(t.device_orientation, out->mutable_device_pose()->mutable_orientation());
  SetVec(t.proxy, out->mutable_proxy_position());
  out->set_tip_radius(t.tip_radius);
  out->set_in_contact(t.in_contact);
  SetVec(t.displayed_force, out->mutable_wrench()->mutable_force());
  SetVec(t.displayed_torque, out->mutable_wrench()->mutable_torque());
  SetVec(t.requested_force, out->mutable_requested()->mutable_force());
  SetVec(t.requested_torque, out->mutable_requested()->mutable_torque());
  SetVec(t.object_force, out->mutable_object_force());
  out->set_lease_holder(lease_holder);
  for (const std::string& f : DeviceFaultList(t)) out->add_faults(f);
  out->set_contact_instance_id(t.contact_instance);
  out->set_emergency_stopped(t.emergency_stopped);
}

void FillDeviceStatus(const DeviceLink& link, v1::DeviceKind kind, const ToolTelemetry& t,
                      const std::pair<std::string, double>& lease, const rt::LoopStats& loop,
                      v1::DeviceStatus* out) {
  const drivers::DeviceInfo& info = link.info();
  out->set_kind(kind);
  out->set_name(info.name);
  out->set_model(info.name + " (" + info.model + ")");
  out->set_connected(t.connected);
  out->set_calibrated(t.calibrated);
  out->set_emergency_stopped(t.emergency_stopped);
  for (int i = 0; i < t.num_motors; ++i) {
    out->add_string_tensions(t.tensions[i]);
    out->add_string_lengths(t.lengths[i]);
  }
  SetVec(ToVec(t.device_position) - ToVec(t.tool_origin), out->mutable_pose()->mutable_position());
  SetQuaternion(t.device_orientation, out->mutable_pose()->mutable_orientation());
  SetVec(t.displayed_force, out->mutable_wrench()->mutable_force());
  SetVec(t.displayed_torque, out->mutable_wrench()->mutable_torque());
  SetVec(t.requested_force, out->mutable_requested_wrench()->mutable_force());
  SetVec(t.requested_torque, out->mutable_requested_wrench()->mutable_torque());
  out->set_max_force(info.max_force);
  out->set_max_stiffness(link.effective_stiffness());
  out->set_lease_holder(lease.first);
  out->set_lease_expires_in_s(lease.second);
  for (const std::string& f : DeviceFaultList(t)) out->add_faults(f);
  out->set_fault_bits(t.faults);
  SetVec(t.proxy, out->mutable_proxy_position());
  out->set_in_contact(t.in_contact);
  SetVec(t.object_force, out->mutable_object_force());
  out->set_contact_instance_id(t.contact_instance);
  FillDeviceCounters(t, out->mutable_counters());
  out->set_min_tension(link.min_tension());
  out->set_tip_radius(t.tip_radius);
  out->set_watchdog_timeout_ms(link.watchdog_timeout_ns() / 1e6);
  SetVec(t.tool_origin, out->mutable_tool_origin());
  FillPercentiles(loop.period, out->mutable_loop_period());
  out->set_loop_late_ticks(loop.late_ticks.load());
}

void FillLease(const LeaseManager::Lease& l, v1::Lease* out) {
  out->set_lease_id(l.id);
  out->set_holder(l.holder);
  out->set_expires_in_s(LeaseManager::SecondsLeft(l));
}

sketch::ContourOptions ToSketchOptions(const v1::ContourOptions& o) {
  sketch::ContourOptions s;
  if (o.epsilon_px() > 0) s.epsilon_px = o.epsilon_px();
  if (o.max_gap_fraction() > 0) s.max_gap_fraction = o.max_gap_fraction();
  return s;
}

void FillContourReport(const sketch::ContourResult& r, v1::ContourReport* out) {
  for (const Vec2& p : r.contour.points) {
    auto* q = out->mutable_contour()->add_points();
    q->set_x(p.x());
    q->set_y(p.y());
  }
  out->set_epsilon_px(r.epsilon_px);
  out->set_distance_to_line_px(r.line_distance_px);
  for (const auto& s : r.repairs) out->add_repairs(s);
  for (const auto& s : r.warnings) out->add_warnings(s);
  for (const auto& t : r.timings) (*out->mutable_timings_ms())[t.stage] += t.ms;
}

void FillMeshReport(const mesh::MeshResult& r, v1::MeshReport* out) {
  const mesh::QualityReport& q = r.quality;
  out->set_vertex_count(static_cast<uint32_t>(q.num_vertices));
  out->set_tetrahedron_count(static_cast<uint32_t>(q.num_tets));
  out->set_surface_triangle_count(static_cast<uint32_t>(q.num_surface_faces));
  out->set_volume(q.tet_volume_sum);
  out->set_surface_volume(q.surface_volume);
  out->set_min_dihedral_deg(q.min_dihedral_deg);
  out->set_median_dihedral_deg(q.median_dihedral_deg);
  out->set_max_radius_edge_ratio(q.max_radius_edge);
  out->set_min_volume_ratio(q.min_volume_ratio);
  out->set_watertight(q.surface_closed && q.surface_manifold && q.surface_outward &&
                      q.boundary_matches_surface);
  for (const auto& t : r.timings) (*out->mutable_timings_ms())[t.stage] += t.seconds * 1e3;
}

}  // namespace rheo::daemon
