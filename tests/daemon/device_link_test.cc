// The device side of the loop without gRPC: the lock-free slot, the network tool fed from other
// threads, the emergency stop from another thread, and the contact on a simulated tetrahedron
// (threads: also run under TSan, label rt).
#include "daemon/device/device_link.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <thread>
#include <vector>

#include "daemon/loop/seq_slot.h"
#include "drivers/device_factory.h"
#include "held_tet.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

struct Payload {
  uint64_t words[16] = {};
};

TEST(SeqSlot, ReadersNeverSeeATornValue) {
  SeqSlot<Payload> slot;
  std::atomic<bool> stop{false};
  std::thread writer([&] {
    Payload p;
    for (uint64_t i = 1; i <= 100000; ++i) {
      for (auto& w : p.words) w = i;
      slot.Store(p);
    }
    stop.store(true);
  });
  std::vector<std::thread> readers;
  std::atomic<int> torn{0}, backwards{0};
  for (int r = 0; r < 3; ++r)
    readers.emplace_back([&] {
      uint64_t last = 0;
      while (!stop.load()) {
        const Payload p = slot.Load();
        for (uint64_t w : p.words)
          if (w != p.words[0]) torn.fetch_add(1);
        if (p.words[0] < last) backwards.fetch_add(1);
        last = p.words[0];
      }
    });
  writer.join();
  for (auto& t : readers) t.join();
  EXPECT_EQ(torn.load(), 0);
  EXPECT_EQ(backwards.load(), 0);
  EXPECT_EQ(slot.Load().words[15], 100000u);
}

EngineOptions TestOptions() {
  EngineOptions o;
  o.loop.realtime_priority = false;
  o.loop.lock_memory = false;
  return o;
}

ToolTelemetry WaitFor(const Engine& e, const std::function<bool(const ToolTelemetry&)>& ok) {
  const int64_t end = rt::Loop::NowNs() + 5'000'000'000;
  ToolTelemetry t = e.tool();
  while (!ok(t) && rt::Loop::NowNs() < end) {
    std::this_thread::sleep_for(std::chrono::microseconds(500));
    t = e.tool();
  }
  return t;
}

TEST(DeviceLink, ALineWhoseExchangesKeepFailingIsReportedDisconnected) {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kSimSpidarG;
  o.config_path = std::string(RHEO_DEVICES) + "/spidar_g_x5.json";
  o.realtime = false;
  o.reply_timeout_us = 20000;
  o.watchdog_timeout_ns = 100'000'000;  // the failing line slows the loop: no watchdog stop
  auto link = DeviceLink::Open(o);
  ASSERT_TRUE(link.ok()) << link.error().message;
  Engine engine(TestOptions());
  engine.AttachDevice(link->get());
  engine.Start();
  ToolTelemetry t = WaitFor(engine, [](const ToolTelemetry& t) { return t.exchanges > 200; });
  EXPECT_TRUE(t.connected);
  // The emulator stops answering: every exchange now fails.
  (*link)->emulator()->Stop();
  const uint64_t errors = t.device_errors;
  t = WaitFor(engine, [](const ToolTelemetry& t) { return !t.connected; });
  EXPECT_FALSE(t.connected) << (t.device_errors - errors) << " failed exchanges";
  EXPECT_GT(t.device_errors, errors);
  engine.Stop();
}

// The emulated board's end of the line goes wrong three ways (no replies, damaged replies,
// replies later than the driver waits): the link reports it (disconnected or a latched fault,
// the failed exchanges counted), the strings are commanded to their minimum tension, and once
// the line is good again the loop clears the stop by itself and the link is connected.
TEST(DeviceLink, LineFaultsAreReportedTheStringsGoSlackAndTheLinkRecovers) {
  struct Case {
    const char* name;
    drivers::LineFault fault;
    int delay_us;
  };
  for (const Case& c : {Case{"silent", drivers::LineFault::kSilent, 0},
                        Case{"corrupt", drivers::LineFault::kCorrupt, 0},
                        Case{"delayed 30 ms", drivers::LineFault::kDelayed, 30000}}) {
    SCOPED_TRACE(c.name);
    DeviceLinkOptions o;
    o.kind = DeviceKind::kSimSpidarG;
    o.config_path = std::string(RHEO_DEVICES) + "/spidar_g_x5.json";
    o.realtime = false;
    o.reply_timeout_us = 20000;
    o.watchdog_timeout_ns = 100'000'000;
    auto link = DeviceLink::Open(o);
    ASSERT_TRUE(link.ok()) << link.error().message;
    drivers::SpidarEmulator& emu = *(*link)->emulator();
    const double min_tension = (*link)->min_tension();
    Engine engine(TestOptions());
    engine.AttachDevice(link->get());
    engine.Start();
    ToolTelemetry t = WaitFor(engine, [](const ToolTelemetry& t) {
      return t.exchanges > 200 && t.connected && t.faults == 0;
    });
    ASSERT_TRUE(t.connected && t.faults == 0);
    const uint64_t errors = t.device_errors + t.protocol_errors, recoveries = t.recoveries;

    emu.SetLineFault(c.fault, c.delay_us);
    t = WaitFor(engine, [](const ToolTelemetry& t) { return !t.connected || t.faults != 0; });
    EXPECT_TRUE(!t.connected || t.faults != 0) << "the fault was not reported";
    EXPECT_GT(t.device_errors + t.protocol_errors, errors);
    // Every string at its minimum tension (the commands still reach the board).
    bool slack = false;
    for (int i = 0; i < 400 && !slack; ++i) {
      const drivers::GripSnapshot g = emu.Snapshot();
      slack = true;
      for (int k = 0; k < g.tensions.size(); ++k)
        slack = slack && g.tensions[k] <= min_tension + 0.01;
      if (!slack) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    EXPECT_TRUE(slack) << "the strings were not commanded to their minimum tension";
    const ToolTelemetry during = engine.tool();

    emu.SetLineFault(drivers::LineFault::kNone);
    t = WaitFor(engine, [](const ToolTelemetry& t) { return t.connected && t.faults == 0; });
    EXPECT_TRUE(t.connected) << "not connected again";
    EXPECT_EQ(t.faults, 0u) << "the stop was not cleared";
    std::printf(
        "%s: reported with faults 0x%x, connected %d; %llu failed exchanges, %llu protocol "
        "errors; strings slack %d; back with %llu recoveries\n",
        c.name, during.faults, during.connected,
        static_cast<unsigned long long>(during.device_errors),
        static_cast<unsigned long long>(during.protocol_errors), slack,
        static_cast<unsigned long long>(t.recoveries - recoveries));
    engine.Stop();
  }
}

// A USB serial adapter pulled out and plugged in again while the hand presses an object: the
// emulator's end of the line closes and later comes back on a new pty behind the same name. The
// loop reports the device disconnected, commands minimum tension, displays and applies nothing,
// and keeps its rate (no tick waits on the port); the reopener thread tries with a growing
// backoff; after the replug the board is identified again, the first command it gets is minimum
// tension, and the loop's recovery clears the stop so the press is felt again.
TEST(DeviceLink, AnUnpluggedLineIsReportedReopenedWithAGrowingBackoffAndTheForceComesBack) {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kSimSpidarG;
  o.config_path = std::string(RHEO_DEVICES) + "/spidar_g_x5.json";
  o.realtime = false;
  o.reply_timeout_us = 20000;
  o.watchdog_timeout_ns = 100'000'000;
  auto link = DeviceLink::Open(o);
  ASSERT_TRUE(link.ok()) << link.error().message;
  drivers::SpidarEmulator& emu = *(*link)->emulator();
  auto config = drivers::LoadSpidarConfigFile(o.config_path);
  ASSERT_TRUE(config.ok()) << config.error().message;
  std::array<int16_t, 8> min_digits;
  for (int i = 0; i < 8; ++i) {
    const auto& s = config->strings[i];
    min_digits[i] = static_cast<int16_t>(std::lround(
        s.command_sign * s.min_tension * s.volts_per_newton * config->board.digits_per_volt));
  }

  // The tetrahedron under the tool: the device frame's origin 1 cm above its apex.
  auto held = testing::MakeHeldTet();
  ASSERT_TRUE(held.ok()) << held.error().message;
  const Vec3 origin(0.012, 0.05, 0.012);
  auto contact =
      (*link)->MakeContact(held->mesh.surface, held->object->positions(), origin, held->min_mass);
  ASSERT_TRUE(contact.ok()) << contact.error().message;
  Engine engine(TestOptions());
  engine.AttachDevice(link->get());
  engine.Start();
  Command place;
  place.type = Command::Type::kSetToolOrigin;
  place.vec = {origin.x(), origin.y(), origin.z()};
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(place), 5'000'000'000));
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 7;
  add.object = held->object.release();
  add.contact = contact->release();
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(add), 5'000'000'000));
  // The hand presses the grip 2 cm down: 1 cm into the apex.
  drivers::Pose down;
  down.position = Vec3(0.0, -0.02, 0.0);
  emu.HoldHand(down);
  ToolTelemetry t = WaitFor(engine, [](const ToolTelemetry& t) {
    return t.connected && t.faults == 0 && t.in_contact && t.displayed_force[1] > 0.2;
  });
  ASSERT_TRUE(t.connected && t.faults == 0 && t.displayed_force[1] > 0.2)
      << "no press: faults 0x" << std::hex << t.faults << std::dec << ", force "
      << t.displayed_force[1] << " N";
  const double pressed = t.displayed_force[1];
  const uint64_t recoveries = t.recoveries;
  const uint64_t enumerations = emu.Snapshot().enumerations;

  const int64_t unplugged = rt::Loop::NowNs();
  ASSERT_TRUE(emu.Unplug().ok());
  t = WaitFor(engine, [](const ToolTelemetry& t) { return !t.connected; });
  const double report_ms = (rt::Loop::NowNs() - unplugged) * 1e-6;
  ASSERT_FALSE(t.connected) << "the unplug was not reported";
  EXPECT_LT(report_ms, 1000.0);
  EXPECT_TRUE(t.faults & drivers::kFaultNotConnected);
  EXPECT_EQ(t.line_losses, 1u);
  // A tick later: nothing displayed, nothing put on the object, every string at minimum.
  t = WaitFor(engine, [&](const ToolTelemetry& u) { return u.tick > t.tick + 2; });
  EXPECT_FALSE(t.object_loaded);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(t.requested_force[k], 0.0);
    EXPECT_EQ(t.object_force[k], 0.0);
  }
  for (int i = 0; i < t.num_motors; ++i)
    EXPECT_NEAR(t.tensions[i], config->strings[i].min_tension, 1e-9);

  // The reopener's attempts, as the loop reports them, while the line is away (nominal 0.1 s
  // after the loss, then 0.2, 0.4 and 0.8 s apart), each with the time the reopener made it and
  // the wait it announced next. The loop keeps ticking all the while.
  std::vector<int64_t> attempt_ns;
  std::vector<double> backoff_after_s;
  uint64_t seen = t.reconnect_attempts;
  double longest_backoff_s = 0.0;
  const uint64_t tick0 = t.tick;
  const int64_t away0 = rt::Loop::NowNs();
  while (attempt_ns.size() < 4 && rt::Loop::NowNs() < away0 + 20'000'000'000) {
    std::this_thread::sleep_for(std::chrono::microseconds(500));
    const double before = t.reconnect_backoff_s;  // the wait that led to this attempt
    t = engine.tool();
    longest_backoff_s = std::max(longest_backoff_s, t.reconnect_backoff_s);
    if (t.reconnect_attempts != seen) {
      EXPECT_EQ(t.reconnect_attempts, seen + 1) << "two attempts between looks 0.5 ms apart";
      seen = t.reconnect_attempts;
      attempt_ns.push_back(t.reconnect_attempt_ns);
      // The next wait, once the reopener has announced it (it follows the failed attempt).
      const int64_t look_until = rt::Loop::NowNs() + 5'000'000'000;
      while (t.reconnect_backoff_s == before && t.reconnect_attempts == seen &&
             rt::Loop::NowNs() < look_until) {
        std::this_thread::sleep_for(std::chrono::microseconds(500));
        t = engine.tool();
      }
      backoff_after_s.push_back(t.reconnect_backoff_s);
    }
  }
  const double away_s = (rt::Loop::NowNs() - away0) * 1e-9;
  const double ticks_per_s = (t.tick - tick0) / away_s;
  ASSERT_EQ(attempt_ns.size(), 4u) << "attempts seen: " << attempt_ns.size();
  EXPECT_FALSE(t.connected);
  EXPECT_EQ(t.reconnects, 0u);
  EXPECT_GT(t.disconnected_s, 1.0);
  EXPECT_GT(longest_backoff_s, 0.5);
  EXPECT_LE(longest_backoff_s, o.reconnect_backoff_max_ns * 1e-9);
  // The wait doubles after each failure: exactly, as announced, and at least that long on the
  // reopener's clock (a busy machine only lengthens a wait; how late the loop publishes the count
  // does not enter).
  const double nominal[3] = {0.2, 0.4, 0.8};
  double gaps[3];
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(backoff_after_s[i], nominal[i], 1e-9) << "the wait announced after attempt " << i;
    gaps[i] = (attempt_ns[i + 1] - attempt_ns[i]) * 1e-9;
    EXPECT_GE(gaps[i], nominal[i] - 1e-3) << "attempts " << i << " and " << i + 1;
  }
  // The loop at its rate (1 kHz) while the port is away: ticks that waited on open() or on a
  // reply timeout (20 ms) would bring it to 50 a second. A quarter of the rate leaves room for a
  // machine loaded by sanitizers and parallel tests.
  EXPECT_GT(ticks_per_s, 250.0);

  const int64_t replugged = rt::Loop::NowNs();
  ASSERT_TRUE(emu.Replug().ok());
  t = WaitFor(engine, [](const ToolTelemetry& t) { return t.reconnects > 0; });
  const double reopen_ms = (rt::Loop::NowNs() - replugged) * 1e-6;
  ASSERT_EQ(t.reconnects, 1u) << "not reopened";
  t = WaitFor(engine, [](const ToolTelemetry& t) {
    return t.connected && t.faults == 0 && t.displayed_force[1] > 0.2;
  });
  const double felt_ms = (rt::Loop::NowNs() - replugged) * 1e-6;
  EXPECT_TRUE(t.connected) << "not connected again";
  EXPECT_EQ(t.faults, 0u) << "the stop was not cleared";
  EXPECT_GT(t.displayed_force[1], 0.2) << "the press is not felt again";
  EXPECT_GE(t.recoveries, recoveries + 1);
  EXPECT_EQ(t.disconnected_s, 0.0);
  EXPECT_EQ(t.reconnect_backoff_s, 0.0);
  const drivers::GripSnapshot g = emu.Snapshot();
  EXPECT_EQ(g.enumerations, enumerations + 1) << "the board was not identified again";
  EXPECT_EQ(g.first_command_on_line, min_digits) << "the first command on the new line";
  std::printf(
      "unplug reported in %.1f ms; attempts %.0f, %.0f, %.0f ms apart (nominal 200, 400, 800); "
      "%.0f ticks/s while away; reopened %.0f ms after the replug, felt again (%.2f N, %.2f N "
      "before) at %.0f ms\n",
      report_ms, gaps[0] * 1e3, gaps[1] * 1e3, gaps[2] * 1e3, ticks_per_s, reopen_ms,
      t.displayed_force[1], pressed, felt_ms);
  engine.Stop();
}

TEST(DeviceLink, NetworkToolPressesATetrahedronWithEqualAndOppositeForces) {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kNetwork;
  o.realtime = false;
  auto link = DeviceLink::Open(o);
  ASSERT_TRUE(link.ok()) << link.error().message;
  NetworkDevice* net = (*link)->network();
  ASSERT_NE(net, nullptr);

  auto held = testing::MakeHeldTet();
  ASSERT_TRUE(held.ok()) << held.error().message;
  // The tool starts 1 cm above the apex; the device frame's origin is the scene origin.
  auto contact = (*link)->MakeContact(held->mesh.surface, held->object->positions(),
                                      Vec3(0.01, 0.05, 0.01), held->min_mass);
  ASSERT_TRUE(contact.ok()) << contact.error().message;

  Engine engine(TestOptions());
  engine.AttachDevice(link->get());
  engine.Start();
  Command add;
  add.type = Command::Type::kAddObject;
  add.instance_id = 7;
  add.object = held->object.release();
  add.contact = contact->release();
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(add), 5'000'000'000));

  // Another thread streams poses down onto the apex's face region, like ToolStream does.
  std::atomic<bool> stop{false};
  std::thread feeder([&] {
    for (int i = 0; !stop.load(); ++i) {
      drivers::Pose pose;
      pose.position = Vec3(0.012, 0.05 - 0.02 * std::min(1.0, i / 200.0), 0.012);
      net->Push(pose, 0);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  ToolTelemetry t = WaitFor(engine, [](const ToolTelemetry& t) {
    return t.in_contact && t.faults == 0 && t.displayed_force[1] > 0.2;
  });
  EXPECT_TRUE(t.in_contact);
  EXPECT_EQ(t.contact_instance, 7u);
  EXPECT_GT(t.displayed_force[1], 0.2);
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(t.object_force[k], -t.displayed_force[k],
                1e-9 + 1e-9 * std::abs(t.displayed_force[1]));
  EXPECT_GT(t.input_seq, 0u);

  // Emergency stop from yet another thread: no force displayed, none put on the object.
  std::thread([&] { (*link)->EmergencyStop(); }).join();
  t = WaitFor(engine, [](const ToolTelemetry& t) {
    return t.emergency_stopped && (t.faults & drivers::kFaultSafeStop);
  });
  t = WaitFor(engine, [&](const ToolTelemetry& u) { return u.tick > t.tick + 2; });
  EXPECT_TRUE(t.emergency_stopped);
  EXPECT_TRUE(t.faults & drivers::kFaultSafeStop);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(t.displayed_force[k], 0.0);
    EXPECT_EQ(t.object_force[k], 0.0);
  }
  // Clearing (the service checks the lease first) brings the force back.
  Command clear;
  clear.type = Command::Type::kDeviceClear;
  ASSERT_TRUE(engine.WaitApplied(engine.Submit(clear), 5'000'000'000));
  t = WaitFor(engine, [](const ToolTelemetry& t) {
    return !t.emergency_stopped && t.faults == 0 && t.displayed_force[1] > 0.2;
  });
  EXPECT_FALSE(t.emergency_stopped);
  EXPECT_GT(t.displayed_force[1], 0.2);
  stop.store(true);
  feeder.join();
  engine.Stop();
}

}  // namespace
}  // namespace rheo::daemon
