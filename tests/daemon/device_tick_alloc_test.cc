// The device's part of the loop tick allocates nothing: exchange (through the emulator's pty, or
// the network tool's slot), contact, node forces, device command, telemetry. Own binary: it
// counts allocations (rheo_test_alloc replaces the global operator new).
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <thread>

#include "alloc_counter.h"
#include "daemon/device/device_link.h"
#include "held_tet.h"
#include "sim/sim.h"

namespace rheo::daemon {
namespace {

// Runs `ticks` ticks of the device side against a held tetrahedron; `move` sets the tool.
void RunTicks(DeviceLink& link, int ticks, const std::function<void(int)>& move, long* allocs,
              int* contact_ticks) {
  auto held = testing::MakeHeldTet();
  ASSERT_TRUE(held.ok()) << held.error().message;
  sim::SimObject* obj = held->object.get();
  auto contact = link.MakeContact(held->mesh.surface, obj->positions(), Vec3(0.012, 0.05, 0.012),
                                  held->min_mass);
  ASSERT_TRUE(contact.ok()) << contact.error().message;
  std::array<EngineSlot, 1> slots{EngineSlot{1, obj, contact->get()}};
  ToolTelemetry out;
  *allocs = 0;
  *contact_ticks = 0;
  for (int i = 0; i < ticks; ++i) {
    move(i);
    rt::TickInfo info;
    info.tick = static_cast<uint64_t>(i);
    info.dt = 1e-3;
    info.deadline_ns = info.start_ns = rt::Loop::NowNs();
    testing::AllocationCounter count;
    obj->Step(info.dt);
    link.Tick(info, slots, &out);
    *allocs += count.count();
    if (out.in_contact) ++*contact_ticks;
  }
  link.Forget(slots[0]);
}

TEST(DeviceTickAlloc, NetworkToolInContactAllocatesNothing) {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kNetwork;
  o.realtime = false;
  auto link = DeviceLink::Open(o);
  ASSERT_TRUE(link.ok()) << link.error().message;
  NetworkDevice* net = (*link)->network();
  long allocs = -1;
  int contact = 0;
  RunTicks(
      **link, 400,
      [&](int i) {
        drivers::Pose pose;
        pose.position = Vec3(0.012, 0.05 - 0.02 * std::min(1.0, i / 200.0), 0.012);
        net->Push(pose, 0);
      },
      &allocs, &contact);
  EXPECT_GT(contact, 50) << "the tool should have touched the tetrahedron";
  EXPECT_EQ(allocs, 0);
}

TEST(DeviceTickAlloc, SpidarGThroughTheEmulatorAllocatesNothing) {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kSimSpidarG;
  o.config_path = std::string(RHEO_DEVICES) + "/spidar_g_x5.json";
  o.realtime = false;
  o.reply_timeout_us = 50000;
  o.watchdog_timeout_ns = 1'000'000'000;  // a test thread, not the real-time loop
  auto link = DeviceLink::Open(o);
  ASSERT_TRUE(link.ok()) << link.error().message;
  long allocs = -1;
  int contact = 0;
  RunTicks(
      **link, 300, [](int) {}, &allocs, &contact);
  EXPECT_EQ(allocs, 0);
  (*link)->Shutdown();
}

// The line pulled out and plugged in again: the ticks while it is away (each exchange failing
// at once) and the tick that takes the reopened line allocate nothing on the loop's thread; the
// reopening (open(), identification, the lost line's close) is the reopener thread's.
TEST(DeviceTickAlloc, SpidarGWithItsLineAwayAndBackAllocatesNothing) {
  DeviceLinkOptions o;
  o.kind = DeviceKind::kSimSpidarG;
  o.config_path = std::string(RHEO_DEVICES) + "/spidar_g_x5.json";
  o.realtime = false;
  o.reply_timeout_us = 50000;
  o.watchdog_timeout_ns = 1'000'000'000;
  o.reconnect_backoff_ns = 20'000'000;
  o.reconnect_backoff_max_ns = 40'000'000;
  auto link = DeviceLink::Open(o);
  ASSERT_TRUE(link.ok()) << link.error().message;
  drivers::SpidarEmulator& emu = *(*link)->emulator();
  long allocs = -1;
  int contact = 0;
  RunTicks(
      **link, 50, [](int) {}, &allocs, &contact);
  EXPECT_EQ(allocs, 0);
  ASSERT_TRUE(emu.Unplug().ok());
  // The tick that finds the line gone builds its error message (the errno's words): once.
  RunTicks(
      **link, 1, [](int) {}, &allocs, &contact);
  RunTicks(
      **link, 300, [](int) {}, &allocs, &contact);
  EXPECT_EQ(allocs, 0) << "ticks with the line away";
  ASSERT_TRUE(emu.Replug().ok());
  // Ticks until the reopened line is taken and answers (the reopener waits 40 ms at most).
  long back_allocs = 0;
  for (int k = 0; k < 100 && emu.Snapshot().commands_on_line < 50; ++k) {
    RunTicks(
        **link, 10, [](int) {}, &allocs, &contact);
    back_allocs += allocs;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_GE(emu.Snapshot().commands_on_line, 50u) << "the line did not come back";
  EXPECT_EQ(back_allocs, 0) << "ticks taking the reopened line";
  (*link)->Shutdown();
}

}  // namespace
}  // namespace rheo::daemon
