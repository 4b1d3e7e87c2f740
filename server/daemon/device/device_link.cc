#include "daemon/device/device_link.h"

#include <cstdio>
#include <thread>

#include "common/format.h"
#include "daemon/device/tool_contact.h"
#include "daemon/device/tool_placement.h"
#include "drivers/device_factory.h"

namespace rheo::daemon {
namespace {

std::array<double, 3> A3(const Vec3& v) {
  return {v.x(), v.y(), v.z()};
}

}  // namespace

Result<DeviceLink::ObjectAttachment> DeviceLink::PrepareObject(
    std::span<const std::array<int32_t, 3>> surface, std::span<const uint32_t> triangles,
    std::span<const Vec3> positions, std::span<const double> masses, bool first_in_scene,
    const ToolTelemetry& now) const {
  ObjectAttachment out;
  Vec3 origin(now.tool_origin[0], now.tool_origin[1], now.tool_origin[2]);
  if (first_in_scene) {
    origin = WorkspaceOriginOver(triangles, positions, renderer_config_.tool_radius);
    out.sets_origin = true;
    out.tool_origin = origin;
  }
  // Where the tool will be once the origin is in place: the grip keeps its device-frame pose.
  const Vec3 grip(now.device_position[0] - now.tool_origin[0],
                  now.device_position[1] - now.tool_origin[1],
                  now.device_position[2] - now.tool_origin[2]);
  out.tool = origin + grip;
  auto made = MakeContact(surface, positions, out.tool, MinSurfaceMass(surface, masses));
  if (!made.ok())
    return Error{made.error().code,
                 "the haptic renderer refused this object's surface: " + made.error().message};
  out.contact = std::move(made).value();
  return out;
}

const char* DeviceKindName(DeviceKind kind) {
  switch (kind) {
    case DeviceKind::kNone: return "none";
    case DeviceKind::kSimSpidarG: return "sim-spidar-g";
    case DeviceKind::kSpidarG: return "spidar-g";
    case DeviceKind::kNetwork: return "network";
  }
  return "?";
}

Result<std::unique_ptr<DeviceLink>> DeviceLink::Open(const DeviceLinkOptions& options) {
  if (options.kind == DeviceKind::kNone)
    return InvalidArgument("DeviceLink::Open: kind none has no device");
  std::unique_ptr<DeviceLink> link(new DeviceLink(options));
  haptics::RendererConfig rc;
  rc.tool_radius = options.tool_radius;
  if (options.kind == DeviceKind::kNetwork) {
    auto net = std::make_unique<NetworkDevice>();
    link->network_ = net.get();
    link->device_ = std::move(net);
  } else {
    auto config = drivers::LoadSpidarConfigFile(options.config_path);
    if (!config.ok()) return config.error();
    rc.device.damping = config->mechanism.damping;
    std::string port = options.port;
    if (options.kind == DeviceKind::kSimSpidarG) {
      drivers::EmulatorOptions eo;
      // The emulated mechanism has the damping the frame file states, so the renderer's
      // passivity bound holds for it as it would for the hardware.
      eo.linear_damping = config->mechanism.damping;
      eo.realtime_priority = options.realtime ? 85 : 0;
      auto emu = drivers::SpidarEmulator::Start(*config, eo);
      if (!emu.ok()) return emu.error();
      link->emulator_ = std::move(emu).value();
      link->emulator_->HoldHand(drivers::Pose());
      // The link's stable name, not the pty it points at now: the driver reopens it after an
      // unplug, as it would /dev/serial/by-id/... of a real adapter.
      port = link->emulator_->line_path();
    }
    if (port.empty())
      return InvalidArgument("--device spidar-g needs --device-port (e.g. /dev/ttyUSB0)");
    drivers::SpidarOpenOptions oo;
    oo.reply_timeout_us = options.reply_timeout_us;
    oo.reopen_options.first_backoff_ns = options.reconnect_backoff_ns;
    oo.reopen_options.max_backoff_ns = options.reconnect_backoff_max_ns;
    oo.reopen_options.log = options.log;
    auto dev = drivers::OpenSpidarG(*config, port, oo);
    if (!dev.ok()) return dev.error();
    link->min_tension_ = config->strings[0].min_tension;
    for (const auto& s : config->strings)
      link->min_tension_ = std::min(link->min_tension_, s.min_tension);
    link->device_ = std::move(dev).value();
  }
  drivers::HapticDevice& d = *link->device_;
  if (options.kind == DeviceKind::kNetwork)  // OpenSpidarG has opened the SPIDAR-G already
    if (Status s = d.Open(); !s.ok()) return s.error();
  if (Status s = d.Calibrate(); !s.ok())
    return Error{s.error().code, "calibrating " + d.info().name + ": " + s.error().message +
                                     " (hold the grip at the frame centre and retry)"};
  const drivers::DeviceInfo& info = d.info();
  rc.device.max_force = info.max_force;
  rc.device.max_force_rate = info.max_force_rate;
  rc.coupling_damping = 0.2 * rc.device.damping;
  if (Status s = rc.Validate(); !s.ok()) return s.error();
  link->renderer_config_ = rc;
  link->effective_stiffness_ = std::min(
      {rc.coupling_stiffness, rc.device.max_stiffness,
       rc.stability_margin * 2.0 * (rc.device.damping - rc.coupling_damping) / rc.device.tick});
  if (options.kind != DeviceKind::kNetwork) {
    // Armed by the first tick: the loop may start a while after this.
    link->dog_ = std::make_unique<drivers::Watchdog>(d, options.watchdog_timeout_ns);
    link->dog_thread_ =
        std::make_unique<drivers::WatchdogThread>(*link->dog_, options.realtime ? 90 : 0);
  }
  link->t_.present = true;
  link->t_.tip_radius = rc.tool_radius;
  link->t_.stiffness = link->effective_stiffness_;
  link->t_.calibrations = 1;
  return link;
}

DeviceLink::~DeviceLink() {
  Shutdown();
}

Result<std::unique_ptr<ObjectContact>> DeviceLink::MakeContact(
    std::span<const std::array<int32_t, 3>> surface, std::span<const Vec3> positions,
    const Vec3& tool, double min_node_mass) const {
  return MakeRendererContact(renderer_config_, surface, positions, tool, min_node_mass);
}

void DeviceLink::EmergencyStop() {
  estop_.store(true, std::memory_order_seq_cst);
  device_->SafeStop();
}

void DeviceLink::ClearStop() {
  device_->ClearFaults();
  // An emergency stop that arrived while clearing must win: stop again.
  if (estop_.load(std::memory_order_seq_cst)) device_->SafeStop();
  if (dog_) dog_->Arm(drivers::MonotonicNowNs());
  healthy_ticks_ = 0;
}

void DeviceLink::Apply(const Command& c) {
  switch (c.type) {
    case Command::Type::kDeviceCalibrate:
      estop_.store(false, std::memory_order_seq_cst);
      if (device_->Calibrate().ok()) {
        ++t_.calibrations;
      } else {
        ++t_.calibration_failures;
      }
      ClearStop();
      break;
    case Command::Type::kDeviceClear:
      estop_.store(false, std::memory_order_seq_cst);
      ClearStop();
      break;
    case Command::Type::kSetToolOrigin: origin_ = Vec3(c.vec[0], c.vec[1], c.vec[2]); break;
    default: break;
  }
}

void DeviceLink::Forget(const EngineSlot& slot) {
  contact_.Forget(slot);
}

void DeviceLink::Tick(const rt::TickInfo& info, std::span<EngineSlot> slots, ToolTelemetry* out) {
  // The exchange comes after the simulation step, which does not read the device: the reply to
  // the command posted at the end of the last tick has had the loop's sleep and the step to
  // arrive, and the pose it carries is exactly as fresh as if it were read first.
  const Status s = device_->Exchange(info.dt);
  const int64_t done = drivers::MonotonicNowNs();
  if (dog_ && !dog_armed_) {
    dog_->Arm(done);
    dog_armed_ = true;
  }
  if (dog_) dog_->Feed(done);
  if (s.ok()) {
    ++t_.exchanges;
  } else {
    ++t_.device_errors;
  }
  // The line to the boards: while it is away every exchange fails at once (no I/O) and the
  // driver's reopener thread opens the port again with a growing backoff.
  const drivers::LineStats& line = device_->status().line;
  t_.line_losses = line.losses;
  t_.reconnect_attempts = line.attempts;
  t_.reconnect_attempt_ns = line.last_attempt_ns;
  t_.reconnects = line.reopens;
  t_.reconnect_backoff_s = line.up ? 0.0 : line.backoff_ns * 1e-9;
  t_.disconnected_s = !line.up && line.down_since_ns > 0 ? (done - line.down_since_ns) * 1e-9 : 0.0;
  // A line whose exchanges keep failing is not a connection, whatever the port says.
  constexpr double kLinkDownAbove = 0.5, kLinkUpBelow = 0.1, kShareWeight = 1.0 / 32.0;
  exchange_failure_share_ += kShareWeight * ((s.ok() ? 0.0 : 1.0) - exchange_failure_share_);
  if (exchange_failure_share_ > kLinkDownAbove) link_down_ = true;
  if (exchange_failure_share_ < kLinkUpBelow) link_down_ = false;

  // A stall (watchdog trip, a missed reply) or a line that went away and is back latched a stop;
  // after enough good ticks, and unless someone pressed the emergency stop, the loop clears it.
  const uint32_t stall =
      drivers::kFaultSafeStop | drivers::kFaultProtocol | drivers::kFaultNotConnected;
  const uint32_t faults = device_->status().faults;
  if ((faults & stall) && s.ok() && !estop_.load(std::memory_order_seq_cst)) {
    if (++healthy_ticks_ >= options_.recover_after_ticks) {
      ClearStop();
      ++t_.recoveries;
    }
  } else {
    healthy_ticks_ = 0;
  }

  const drivers::ToolState& tool = device_->state();
  const Vec3 position = origin_ + tool.pose.position;
  // The object feels the tool only while the device displays its reaction.
  const bool loaded = device_->status().faults == drivers::kFaultNone;
  const ContactTick c = contact_.Update(slots, position, tool.linear_velocity, info.dt, loaded);
  if (c.instance_id != 0) t_.stiffness = c.stiffness;
  if (c.renderer_error) ++t_.renderer_errors;
  drivers::Wrench command;
  command.force = c.force;
  command.torque = c.torque;
  // The renderer's wrench is the force on the hand: what the strings pull the grip with.
  device_->SetWrench(command);
  // The command leaves now; its reply arrives while the loop sleeps and steps. A tick whose
  // exchange failed already counts once.
  if (!device_->Post().ok() && s.ok()) ++t_.device_errors;
  // A command that leaves after the next tick's deadline reaches the motors a period late.
  if (drivers::MonotonicNowNs() - info.deadline_ns > static_cast<int64_t>(info.dt * 1e9))
    ++t_.deadline_misses;

  const drivers::DeviceStatus& st = device_->status();
  t_.connected = st.connected && !link_down_;
  t_.calibrated = st.calibrated;
  t_.in_contact = c.in_contact;
  t_.object_loaded = loaded;
  t_.emergency_stopped = estop_.load(std::memory_order_relaxed);
  t_.watchdog_tripped = dog_ && dog_->tripped();
  t_.watchdog_trips = dog_ ? dog_->trips() : 0;
  t_.faults = st.faults;
  t_.contact_instance = c.instance_id;
  t_.num_motors = std::min(st.num_motors, 8);
  t_.device_position = A3(position);
  t_.device_velocity = A3(tool.linear_velocity);
  const Eigen::Quaterniond& q = tool.pose.orientation;
  t_.device_orientation = {q.w(), q.x(), q.y(), q.z()};
  t_.proxy = A3(c.proxy);
  t_.tool_origin = A3(origin_);
  t_.requested_force = A3(st.requested.force);
  t_.requested_torque = A3(st.requested.torque);
  t_.displayed_force = A3(st.displayed.force);
  t_.displayed_torque = A3(st.displayed.torque);
  t_.object_force = A3(c.object_force);
  for (int i = 0; i < 8; ++i) {
    t_.tensions[i] = i < t_.num_motors ? st.tensions[i] : 0.0;
    t_.lengths[i] = i < t_.num_motors ? st.lengths[i] : 0.0;
  }
  t_.protocol_errors = st.protocol_errors;
  t_.input_seq = network_ ? network_->used_seq() : 0;
  *out = t_;
}

std::string DeviceLink::Shutdown() {
  if (!device_) {
    if (emulator_) emulator_->Stop();
    return "";
  }
  if (dog_) dog_->Disarm();
  if (dog_thread_) dog_thread_->Stop();
  const uint64_t before = emulator_ ? emulator_->Snapshot().current_commands : 0;
  // Close() safe-stops again: a second minimum-tension command in case the first was lost.
  device_->SafeStop();
  device_->Close();
  std::string line;
  if (emulator_) {
    // On a busy machine the pty may deliver the stop commands after the driver gave up waiting
    // for the reply: give the emulator up to 1 s to take both.
    drivers::GripSnapshot snap = emulator_->Snapshot();
    for (int i = 0; i < 200 && snap.current_commands < before + 2; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      snap = emulator_->Snapshot();
    }
    line = "emulator: " + std::to_string(snap.current_commands - before) +
           " command(s) during the stop; ";
    line += "last command received sets string tensions [";
    bool all_min = true;
    for (int i = 0; i < snap.tensions.size(); ++i) {
      if (i) line += ' ';
      line += Fixed(snap.tensions[i], 3);
      if (snap.tensions[i] > min_tension_ + 0.01) all_min = false;
    }
    line += Format("] N; minimum %.3f N; all at minimum: %s", min_tension_, all_min ? "yes" : "no");
  }
  dog_thread_.reset();
  dog_.reset();
  device_.reset();
  network_ = nullptr;
  if (emulator_) emulator_->Stop();
  emulator_.reset();
  return line;
}

}  // namespace rheo::daemon
