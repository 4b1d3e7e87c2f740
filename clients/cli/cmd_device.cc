// `rheoctl device status|calibrate|estop|lease|push|hand`: the haptic device.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <string>
#include <thread>

#include "rheo/v1/device.grpc.pb.h"
#include "rheoctl.h"

namespace rheoctl {
namespace {

using DevStub = rheo::v1::DeviceService::Stub;

void PrintDeviceStatus(const rheo::v1::DeviceStatus& st) {
  auto v = [](const rheo::v1::Vec3& a) {
    char b[96];
    std::snprintf(b, sizeof b, "(%.4f, %.4f, %.4f)", a.x(), a.y(), a.z());
    return std::string(b);
  };
  std::printf("device %s: %s\n", rheo::v1::DeviceKind_Name(st.kind()).c_str(), st.model().c_str());
  std::printf("  connected %s, calibrated %s, emergency stop %s\n", st.connected() ? "yes" : "no",
              st.calibrated() ? "yes" : "no", st.emergency_stopped() ? "ENGAGED" : "off");
  std::string faults;
  for (const auto& f : st.faults()) faults += (faults.empty() ? "" : ", ") + f;
  std::printf("  faults: %s\n", faults.empty() ? "none" : faults.c_str());
  if (st.kind() == rheo::v1::DEVICE_KIND_NONE) return;
  std::printf("  grip %s m (device frame); proxy %s m; in contact %s (instance %u)\n",
              v(st.pose().position()).c_str(), v(st.proxy_position()).c_str(),
              st.in_contact() ? "yes" : "no", st.contact_instance_id());
  std::printf("  hand force %s N (requested %s N), object force %s N\n",
              v(st.wrench().force()).c_str(), v(st.requested_wrench().force()).c_str(),
              v(st.object_force()).c_str());
  if (st.string_tensions_size() > 0) {
    std::printf("  tensions [N]:");
    for (double t : st.string_tensions()) std::printf(" %.3f", t);
    std::printf("  (minimum %.3f)\n", st.min_tension());
  }
  std::printf(
      "  max force %.1f N, coupling stiffness %.0f N/m, tip radius %.1f mm, watchdog %.1f ms\n",
      st.max_force(), st.max_stiffness(), st.tip_radius() * 1e3, st.watchdog_timeout_ms());
  const auto& c = st.counters();
  std::printf(
      "  exchanges %llu, device errors %llu, protocol errors %llu, deadline misses %llu, watchdog "
      "trips %llu, recoveries %llu, renderer errors %llu\n",
      (unsigned long long)c.exchanges(), (unsigned long long)c.device_errors(),
      (unsigned long long)c.protocol_errors(), (unsigned long long)c.deadline_misses(),
      (unsigned long long)c.watchdog_trips(), (unsigned long long)c.recoveries(),
      (unsigned long long)c.renderer_errors());
  PrintLineCounters(c);
  std::printf("  loop period p50 %.1f us, p99 %.1f us, max %.1f us; %llu late ticks\n",
              st.loop_period().p50_us(), st.loop_period().p99_us(), st.loop_period().max_us(),
              (unsigned long long)st.loop_late_ticks());
  std::printf("  lease: %s\n", st.lease_holder().empty()
                                   ? "free"
                                   : (st.lease_holder() + " (" +
                                      std::to_string(st.lease_expires_in_s()) + " s left)")
                                         .c_str());
}

int DeviceStatus(const Global& g, bool json) {
  rheo::v1::DeviceStatus st;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::GetDeviceStatus,
                                                  rheo::v1::GetDeviceStatusRequest(), &st);
  if (!s.ok()) return Fail(s);
  if (json) {
    std::cout << ToJson(st, true);
  } else {
    PrintDeviceStatus(st);
  }
  return 0;
}

int DeviceCalibrate(const Global& g, const std::string& lease) {
  rheo::v1::CalibrateRequest req;
  req.set_lease_id(lease);
  rheo::v1::CalibrateResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::Calibrate, req, &r);
  if (!s.ok()) return Fail(s);
  PrintDeviceStatus(r.status());
  return 0;
}

int DeviceEstop(const Global& g, bool clear, const std::string& lease) {
  rheo::v1::EmergencyStopRequest req;
  req.set_engage(!clear);
  req.set_lease_id(lease);
  rheo::v1::EmergencyStopResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::EmergencyStop, req, &r);
  if (!s.ok()) return Fail(s);
  PrintDeviceStatus(r.status());
  return 0;
}

int LeaseAcquire(const Global& g, const std::string& name, double duration) {
  rheo::v1::AcquireLeaseRequest req;
  req.set_client_name(name);
  req.set_duration_s(duration);
  rheo::v1::Lease l;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::AcquireLease, req, &l);
  if (!s.ok()) return Fail(s);
  std::printf("%s\n", l.lease_id().c_str());
  std::fprintf(stderr, "lease for %s, %.1f s; renew with: rheoctl device lease renew %s\n",
               l.holder().c_str(), l.expires_in_s(), l.lease_id().c_str());
  return 0;
}

int LeaseRenew(const Global& g, const std::string& id, double duration) {
  rheo::v1::RenewLeaseRequest req;
  req.set_lease_id(id);
  req.set_duration_s(duration);
  rheo::v1::Lease l;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::RenewLease, req, &l);
  if (!s.ok()) return Fail(s);
  std::printf("%s %.1f s\n", l.lease_id().c_str(), l.expires_in_s());
  return 0;
}

int LeaseRelease(const Global& g, const std::string& id) {
  rheo::v1::ReleaseLeaseRequest req;
  req.set_lease_id(id);
  rheo::v1::ReleaseLeaseResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::ReleaseLease, req, &r);
  return s.ok() ? 0 : Fail(s);
}

int LeaseRevoke(const Global& g) {
  rheo::v1::RevokeLeaseResponse r;
  grpc::Status s =
      Unary<rheo::v1::DeviceService>(g, &DevStub::RevokeLease, rheo::v1::RevokeLeaseRequest(), &r);
  if (!s.ok()) return Fail(s);
  std::printf("%s\n", r.holder().empty() ? "no lease was live"
                                         : ("revoked the lease of " + r.holder()).c_str());
  return 0;
}

int DeviceHand(const Global& g, const rheo::v1::SimulatedHandRequest& req, double report_s) {
  rheo::v1::SimulatedHandResponse r;
  grpc::Status s = Unary<rheo::v1::DeviceService>(g, &DevStub::SimulatedHand, req, &r);
  if (!s.ok()) return Fail(s);
  if (req.has_press())
    std::printf(
        "pressing object %u: its surface at y = %.4f m; hand target (%.4f, %.4f, %.4f) m (device "
        "frame)\n",
        r.instance_id(), r.surface_y(), r.target().position().x(), r.target().position().y(),
        r.target().position().z());
  if (report_s < 0) report_s = r.seconds() + 0.5;  // until the hand arrived, and a little more
  if (report_s <= 0) return 0;
  // Report the contact as the hand moves: one line every 200 ms.
  const auto end = std::chrono::steady_clock::now() +
                   std::chrono::milliseconds(static_cast<int64_t>(report_s * 1000));
  while (std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    rheo::v1::DeviceStatus st;
    s = Unary<rheo::v1::DeviceService>(g, &DevStub::GetDeviceStatus,
                                       rheo::v1::GetDeviceStatusRequest(), &st);
    if (!s.ok()) return Fail(s);
    std::printf("grip y %+.4f m  contact %-3s  hand force y %+7.3f N  object force y %+7.3f N\n",
                st.pose().position().y(), st.in_contact() ? "yes" : "no", st.wrench().force().y(),
                st.object_force().y());
  }
  return 0;
}

}  // namespace

void AddDeviceCommand(CLI::App& app, const Global& g) {
  struct DeviceArgs {
    std::string lease_id, lease_name;
    double duration = 0, depth = 0.005, seconds = 1.0, report = -1;
    bool clear = false, release_hand = false, json = false;
    std::vector<double> hold, at;
    uint32_t object = 0;
  };
  auto a = std::make_shared<DeviceArgs>();
  auto* device = app.add_subcommand("device", "the haptic device: status, lease, stop, hand");
  device->require_subcommand(1);
  auto* dev_status = device->add_subcommand("status", "pose, forces, tensions, faults, counters");
  dev_status->add_flag("--json", a->json, "print the DeviceStatus message as JSON");
  dev_status->callback([&g, a] { g_exit_code = DeviceStatus(g, a->json); });
  auto* dev_cal = device->add_subcommand(
      "calibrate", "hold the grip at the frame centre; clears faults and the emergency stop");
  dev_cal->add_option("--lease", a->lease_id, "lease id (needed while someone holds the lease)");
  dev_cal->callback([&g, a] { g_exit_code = DeviceCalibrate(g, a->lease_id); });
  auto* dev_estop = device->add_subcommand(
      "estop", "emergency stop: every motor to minimum tension until the lease holder clears it");
  dev_estop->add_flag("--clear", a->clear, "clear the emergency stop (needs --lease)");
  dev_estop->add_option("--lease", a->lease_id, "lease id");
  dev_estop->callback([&g, a] { g_exit_code = DeviceEstop(g, a->clear, a->lease_id); });
  auto* dev_lease = device->add_subcommand("lease", "the control lease (one holder at a time)");
  dev_lease->require_subcommand(1);
  auto* lease_acq = dev_lease->add_subcommand("acquire", "prints the lease id on stdout");
  lease_acq->add_option("--name", a->lease_name, "shown to others as the holder");
  lease_acq->add_option("--duration", a->duration, "lease length [s] (0: 10)");
  lease_acq->callback([&g, a] { g_exit_code = LeaseAcquire(g, a->lease_name, a->duration); });
  auto* lease_renew = dev_lease->add_subcommand("renew", "extend a lease");
  lease_renew->add_option("LEASE", a->lease_id)->required();
  lease_renew->add_option("--duration", a->duration, "new length from now [s] (0: 10)");
  lease_renew->callback([&g, a] { g_exit_code = LeaseRenew(g, a->lease_id, a->duration); });
  auto* lease_rel = dev_lease->add_subcommand("release", "give the lease back");
  lease_rel->add_option("LEASE", a->lease_id)->required();
  lease_rel->callback([&g, a] { g_exit_code = LeaseRelease(g, a->lease_id); });
  dev_lease->add_subcommand("revoke", "admin: end whoever's lease is live")->callback([&g] {
    g_exit_code = LeaseRevoke(g);
  });
  auto* dev_push = device->add_subcommand(
      "push",
      "sim-spidar-g: the emulated hand presses the tool into an object (the one below the tool, "
      "else the first; --object N or --at X Z to choose)");
  dev_push->add_option("--depth", a->depth, "how far below the surface the hand aims [m]")
      ->capture_default_str();
  dev_push->add_option("--seconds", a->seconds, "ramp time [s]")->capture_default_str();
  dev_push->add_option("--object", a->object, "press this scene instance, at the top of it");
  dev_push->add_option("--at", a->at, "press at this scene point x z [m]")->expected(2);
  dev_push->add_option("--lease", a->lease_id, "lease id (needed while someone holds the lease)");
  dev_push->add_option(
      "--report", a->report,
      "print the contact every 200 ms for this long [s] (default: until the hand arrived + "
      "0.5 s)");
  dev_push->callback([&g, a] {
    rheo::v1::SimulatedHandRequest req;
    req.set_lease_id(a->lease_id);
    req.mutable_press()->set_depth_m(a->depth);
    req.mutable_press()->set_seconds(a->seconds);
    req.mutable_press()->set_instance_id(a->object);
    if (a->at.size() == 2) {
      req.mutable_press()->mutable_at()->set_x(a->at[0]);
      req.mutable_press()->mutable_at()->set_z(a->at[1]);
    }
    g_exit_code = DeviceHand(g, req, a->report);
  });
  auto* dev_hand = device->add_subcommand("hand", "sim-spidar-g: hold the grip or let it go");
  dev_hand->add_option("--hold", a->hold, "hold at x y z, device frame [m]")->expected(3);
  dev_hand->add_flag("--release", a->release_hand, "let go of the grip");
  dev_hand->add_option("--lease", a->lease_id, "lease id");
  dev_hand->callback([&g, a] {
    rheo::v1::SimulatedHandRequest req;
    req.set_lease_id(a->lease_id);
    if (a->release_hand) {
      req.set_release(true);
    } else if (a->hold.size() == 3) {
      req.mutable_hold()->mutable_position()->set_x(a->hold[0]);
      req.mutable_hold()->mutable_position()->set_y(a->hold[1]);
      req.mutable_hold()->mutable_position()->set_z(a->hold[2]);
      req.mutable_hold()->mutable_orientation()->set_w(1.0);
    } else {
      std::cerr << "INVALID_ARGUMENT: give --hold x y z or --release\n";
      g_exit_code = 3;
      return;
    }
    g_exit_code = DeviceHand(g, req, 0);
  });
}

}  // namespace rheoctl
