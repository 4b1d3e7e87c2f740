// The SPIDAR-G driver end to end: termios transport, UART board protocol, pose solver and QP
// against the emulator on a pseudo-terminal (lockstep: 1 ms of physics per exchange).
#include <gtest/gtest.h>

#include <thread>

#include "alloc_counter.h"
#include "drivers/device_factory.h"
#include "drivers/spidar_emulator.h"
#include "drivers/spidar_g.h"
#include "drivers/termios_transport.h"
#include "drivers/uart_motor_link.h"
#include "drivers/watchdog.h"
#include "test_util.h"

namespace rheo::drivers {
namespace {

constexpr double kDt = 1e-3;
constexpr double kDeg = M_PI / 180.0;

class SpidarDeviceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    config_ = testutil::LoadFrame("x5");
    EmulatorOptions opt;
    opt.lockstep = true;
    auto emu = SpidarEmulator::Start(config_, opt);
    ASSERT_TRUE(emu.ok()) << emu.error().message;
    emu_ = std::move(emu).value();
    // A generous reply timeout: this machine may be busy; nothing here measures time.
    auto dev = OpenSpidarG(config_, emu_->pty_path(), {.reply_timeout_us = 200'000});
    ASSERT_TRUE(dev.ok()) << dev.error().message;
    dev_ = std::move(dev).value();
  }

  // Runs n ticks: exchange, then command `w`.
  void Run(int n, const Wrench& w = Wrench()) {
    for (int k = 0; k < n; ++k) {
      Status s = dev_->Exchange(kDt);
      ASSERT_TRUE(s.ok()) << s.error().message;
      dev_->SetWrench(w);
    }
  }

  void CalibrateAtHome() {
    emu_->HoldHand(Pose());
    Run(300);  // let the grip settle in the hand under minimum tension
    calibration_truth_ = emu_->Snapshot().pose;
    Status cal = dev_->Calibrate();
    ASSERT_TRUE(cal.ok()) << cal.error().message;
    EXPECT_TRUE(dev_->status().calibrated);
  }

  std::array<int16_t, 8> MinDigits() const {
    std::array<int16_t, 8> d;
    for (int i = 0; i < 8; ++i) {
      const auto& s = config_.strings[i];
      d[i] = static_cast<int16_t>(std::lround(s.command_sign * s.min_tension * s.volts_per_newton *
                                              config_.board.digits_per_volt));
    }
    return d;
  }

  SpidarConfig config_;
  std::unique_ptr<SpidarEmulator> emu_;
  std::unique_ptr<SpidarG> dev_;
  Pose calibration_truth_;
};

TEST_F(SpidarDeviceTest, EnumeratesAndHoldsMinimumTensionUntilCalibrated) {
  EXPECT_NE(dev_->info().model.find("model 7, 8 motors"), std::string::npos) << dev_->info().model;
  EXPECT_EQ(emu_->Snapshot().enumerations, 1u);
  EXPECT_TRUE(dev_->status().connected);
  EXPECT_TRUE(dev_->status().faults & kFaultNotCalibrated);
  Run(20, Wrench{Vec3(3.0, 0.0, 0.0), Vec3::Zero()});  // ignored: not calibrated
  GripSnapshot s = emu_->Snapshot();
  EXPECT_EQ(s.last_command, MinDigits());
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(s.tensions[i], config_.strings[i].min_tension, 2e-3);
  EXPECT_EQ(s.protocol_errors, 0u);
}

TEST_F(SpidarDeviceTest, ReadsThePoseTheHandMovesTheGripTo) {
  CalibrateAtHome();
  Pose target;
  target.position = Vec3(0.03, -0.02, 0.025);
  target.orientation = Eigen::AngleAxisd(15 * kDeg, Vec3(1, 2, 0.5).normalized());
  // The hand moves there over 0.5 s along a smooth path, then holds.
  const double start = emu_->Snapshot().time;
  emu_->ScriptHand([target, start](double t) {
    const double s = std::clamp((t - start) / 0.5, 0.0, 1.0);
    const double e = s * s * (3 - 2 * s);
    Pose p;
    p.position = e * target.position;
    p.orientation = Eigen::Quaterniond::Identity().slerp(e, target.orientation);
    return p;
  });
  double max_err = 0.0;
  for (int k = 0; k < 1000; ++k) {
    Run(1);
    // Compare each tick, including while moving (the driver pose is one exchange old at most).
    GripSnapshot s = emu_->Snapshot();
    Vec3 truth = s.pose.position - calibration_truth_.position;
    max_err = std::max(max_err, (dev_->state().pose.position - truth).norm());
  }
  GripSnapshot s = emu_->Snapshot();
  EXPECT_LT((s.pose.position - target.position).norm(), 1e-3);  // the hand got it there
  const Vec3 truth = s.pose.position - calibration_truth_.position;
  EXPECT_LT((dev_->state().pose.position - truth).norm(), 0.1e-3);
  EXPECT_LT(dev_->state().pose.orientation.angularDistance(s.pose.orientation), 0.2 * kDeg);
  EXPECT_LT(max_err, 0.5e-3);
  EXPECT_EQ(dev_->status().faults, kFaultNone) << FaultNames(dev_->status().faults);
}

TEST_F(SpidarDeviceTest, CommandedWrenchActsOnTheGripAndTheHandFeelsIt) {
  CalibrateAtHome();
  const Wrench w{Vec3(2.0, 0.5, -1.0), Vec3(0.0, 0.01, 0.005)};
  Run(10, w);
  // The real path (termios, UART codec, pose, QP) allocates nothing on the loop thread.
  const long allocations = rheo::testing::ThreadAllocations();
  Run(390, w);
  EXPECT_EQ(rheo::testing::ThreadAllocations() - allocations, 0);
  const GripSnapshot s = emu_->Snapshot();
  const DeviceStatus& st = dev_->status();
  EXPECT_EQ(st.faults, kFaultNone) << FaultNames(st.faults);
  EXPECT_LT((st.displayed.force - w.force).norm(), 1e-6);
  EXPECT_LT((st.displayed.torque - w.torque).norm(), 1e-6);
  // On the emulated grip: the strings' wrench, within the command quantisation (2 mN per
  // string) and the pose error.
  EXPECT_LT((s.strings.force - w.force).norm(), 0.02) << s.strings.force.transpose();
  EXPECT_LT((s.strings.torque - w.torque).norm(), 5e-4) << s.strings.torque.transpose();
  // At rest the hand holds against it (and the grip's weight): equal and opposite.
  const Vec3 weight(0.0, -9.81 * 0.05, 0.0);
  EXPECT_LT((s.hand.force + s.strings.force + weight).norm(), 0.01);
  for (int i = 0; i < 8; ++i) {
    EXPECT_GE(st.tensions[i], config_.strings[i].min_tension);
    EXPECT_LE(st.tensions[i], config_.strings[i].max_tension);
  }
}

TEST_F(SpidarDeviceTest, VelocityFollowsTheHand) {
  CalibrateAtHome();
  const double start = emu_->Snapshot().time;
  emu_->ScriptHand([start](double t) {
    Pose p;
    p.position = Vec3(0.1 * (t - start), 0.0, 0.0);  // 0.1 m/s along x
    return p;
  });
  Run(400);
  EXPECT_NEAR(dev_->state().linear_velocity.x(), 0.1, 0.01);
  EXPECT_NEAR(dev_->state().linear_velocity.y(), 0.0, 0.01);
  EXPECT_NEAR(emu_->Snapshot().velocity.x(), 0.1, 0.01);
}

TEST_F(SpidarDeviceTest, ForceAndForceRateLimits) {
  CalibrateAtHome();
  dev_->SetWrench(Wrench{Vec3(0, 0, 5.0), Vec3::Zero()});
  // One tick of max_force_rate (2000 N/s) allows 2 N.
  EXPECT_NEAR(dev_->status().requested.force.norm(), config_.limits.max_force_rate * kDt, 1e-9);
  EXPECT_TRUE(dev_->status().limited);
  Run(50, Wrench{Vec3(0, 0, 50.0), Vec3::Zero()});
  EXPECT_NEAR(dev_->status().requested.force.z(), config_.limits.max_force, 1e-9);
  EXPECT_TRUE(dev_->status().limited);
  // The X5 strings cannot show 10 N: the displayed force is less, never more.
  EXPECT_LE(dev_->status().displayed.force.norm(), config_.limits.max_force + 1e-9);
}

TEST_F(SpidarDeviceTest, WorkspaceGuardDropsToMinimumTensionAndRecovers) {
  CalibrateAtHome();
  const Wrench w{Vec3(1.0, 0.0, 0.0), Vec3::Zero()};
  Pose out;
  out.position = Vec3(config_.workspace.half_extent.x() + 0.01, 0.0, 0.0);
  emu_->HoldHand(out);
  Run(500, w);
  EXPECT_TRUE(dev_->status().faults & kFaultWorkspace);
  EXPECT_EQ(emu_->Snapshot().last_command, MinDigits());
  emu_->HoldHand(Pose());
  Run(500, w);
  EXPECT_EQ(dev_->status().faults, kFaultNone) << FaultNames(dev_->status().faults);
  EXPECT_LT((emu_->Snapshot().strings.force - w.force).norm(), 0.02);
}

TEST_F(SpidarDeviceTest, SafeStopFromAnotherThreadLatchesMinimumTension) {
  CalibrateAtHome();
  const Wrench w{Vec3(0.0, 2.0, 0.0), Vec3::Zero()};
  Run(100, w);
  EXPECT_NE(emu_->Snapshot().last_command, MinDigits());
  const uint64_t before = emu_->Snapshot().current_commands;
  std::thread([this] { dev_->SafeStop(); }).join();
  GripSnapshot s = emu_->Snapshot();
  EXPECT_EQ(s.current_commands, before + 1);  // SafeStop sent a command of its own
  EXPECT_EQ(s.last_command, MinDigits());
  Run(50, w);  // the loop keeps asking for force: still minimum tension
  EXPECT_TRUE(dev_->status().faults & kFaultSafeStop);
  EXPECT_EQ(emu_->Snapshot().last_command, MinDigits());
  dev_->ClearFaults();
  Run(50, w);
  EXPECT_EQ(dev_->status().faults, kFaultNone) << FaultNames(dev_->status().faults);
  EXPECT_LT((emu_->Snapshot().strings.force - w.force).norm(), 0.02);
}

// The daemon's order: Exchange reads the reply to the command Post sent at the end of the
// previous tick, so the wait for the reply is outside the tick.
TEST_F(SpidarDeviceTest, PostedTicksSendOneCommandEachAndDisplayTheWrench) {
  CalibrateAtHome();
  const Wrench w{Vec3(1.5, -0.5, 1.0), Vec3(0.005, 0.0, -0.01)};
  auto posted_ticks = [&](int n) {
    for (int k = 0; k < n; ++k) {
      Status s = dev_->Exchange(kDt);
      ASSERT_TRUE(s.ok()) << s.error().message;
      dev_->SetWrench(w);
      s = dev_->Post();
      ASSERT_TRUE(s.ok()) << s.error().message;
    }
  };
  posted_ticks(10);
  // Once the last posted command's reply is read, the emulator has counted that command.
  ASSERT_TRUE(dev_->Exchange(kDt).ok());
  const uint64_t before = emu_->Snapshot().current_commands;
  const long allocations = rheo::testing::ThreadAllocations();
  dev_->SetWrench(w);
  ASSERT_TRUE(dev_->Post().ok());
  posted_ticks(389);
  ASSERT_TRUE(dev_->Exchange(kDt).ok());
  EXPECT_EQ(rheo::testing::ThreadAllocations() - allocations, 0);
  const GripSnapshot s = emu_->Snapshot();
  EXPECT_EQ(s.current_commands, before + 390);  // one command per tick, none repeated
  EXPECT_EQ(s.protocol_errors, 0u);
  EXPECT_EQ(dev_->status().protocol_errors, 0u);
  EXPECT_EQ(dev_->status().faults, kFaultNone) << FaultNames(dev_->status().faults);
  EXPECT_LT((s.strings.force - w.force).norm(), 0.02) << s.strings.force.transpose();
  EXPECT_LT((s.strings.torque - w.torque).norm(), 5e-4) << s.strings.torque.transpose();
  // The pose the driver read is the grip's (one exchange old at most).
  const Vec3 truth = s.pose.position - calibration_truth_.position;
  EXPECT_LT((dev_->state().pose.position - truth).norm(), 0.1e-3);
}

// The watchdog's SafeStop may land between Post and the next Exchange, with a reply
// outstanding: it reads that reply itself and sends minimum tension, and the stream stays in
// step for both.
TEST_F(SpidarDeviceTest, SafeStopWithAReplyOutstandingKeepsTheStreamInStep) {
  CalibrateAtHome();
  const Wrench w{Vec3(0.0, 2.0, 0.0), Vec3::Zero()};
  Run(100, w);
  EXPECT_NE(emu_->Snapshot().last_command, MinDigits());
  const uint64_t before = emu_->Snapshot().current_commands;
  ASSERT_TRUE(dev_->Post().ok());
  std::thread([this] { dev_->SafeStop(); }).join();
  GripSnapshot s = emu_->Snapshot();
  EXPECT_EQ(s.current_commands, before + 2);  // the posted command, then SafeStop's own
  EXPECT_EQ(s.last_command, MinDigits());
  // The loop's Exchange finds its reply taken and exchanges in full; no protocol error.
  ASSERT_TRUE(dev_->Exchange(kDt).ok());
  EXPECT_TRUE(dev_->status().faults & kFaultSafeStop);
  EXPECT_EQ(dev_->status().protocol_errors, 0u);
  for (int k = 0; k < 50; ++k) {
    ASSERT_TRUE(dev_->Exchange(kDt).ok());
    dev_->SetWrench(w);
    ASSERT_TRUE(dev_->Post().ok());
  }
  EXPECT_EQ(emu_->Snapshot().last_command, MinDigits());
  EXPECT_EQ(emu_->Snapshot().protocol_errors, 0u);
  EXPECT_EQ(dev_->status().protocol_errors, 0u);
}

TEST(UartMotorLinkSplit, CollectWithoutPostIsRefused) {
  const SpidarConfig config = testutil::LoadFrame("x5");
  EmulatorOptions opt;
  opt.lockstep = true;
  auto emu = SpidarEmulator::Start(config, opt);
  ASSERT_TRUE(emu.ok()) << emu.error().message;
  auto transport = TermiosTransport::Open((*emu)->pty_path());
  ASSERT_TRUE(transport.ok()) << transport.error().message;
  UartMotorLink link(std::move(transport).value(), config.board.board_ids, 200'000);
  ASSERT_TRUE(link.Open(8).ok());
  std::array<int64_t, 8> counts{};
  uint32_t buttons = 0;
  Status s = link.Collect(counts, &buttons);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kFailedPrecondition);
  // Post, then a full exchange: the posted reply is dropped, not mistaken for the new one.
  std::array<int16_t, 8> command{};
  ASSERT_TRUE(link.Post(command).ok());
  EXPECT_TRUE(link.posted());
  ASSERT_TRUE(link.Exchange(command, counts, &buttons).ok());
  EXPECT_FALSE(link.posted());
  ASSERT_TRUE(link.Post(command).ok());
  ASSERT_TRUE(link.Collect(counts, &buttons).ok());
  EXPECT_EQ((*emu)->Snapshot().current_commands, 3u);
  EXPECT_EQ((*emu)->Snapshot().protocol_errors, 0u);
}

TEST_F(SpidarDeviceTest, WatchdogTripsOnAStarvedLoop) {
  CalibrateAtHome();
  Run(100, Wrench{Vec3(0.0, 0.0, 2.0), Vec3::Zero()});
  Watchdog dog(*dev_, 2'000'000);
  const int64_t t0 = 1'000'000'000;
  dog.Arm(t0);
  for (int k = 1; k <= 10; ++k) {  // fed every millisecond: never trips
    dog.Feed(t0 + k * 1'000'000);
    EXPECT_FALSE(dog.Check(t0 + k * 1'000'000 + 500'000));
  }
  EXPECT_NE(emu_->Snapshot().last_command, MinDigits());
  const int64_t last_feed = t0 + 10'000'000;
  EXPECT_FALSE(dog.Check(last_feed + 2'000'000));  // exactly the timeout: not yet
  EXPECT_TRUE(dog.Check(last_feed + 2'000'001));
  EXPECT_EQ(emu_->Snapshot().last_command, MinDigits());
  EXPECT_EQ(dog.trips(), 1u);
  EXPECT_TRUE(dog.Check(last_feed + 3'000'000));  // stays tripped, no second SafeStop
  EXPECT_EQ(dog.trips(), 1u);
}

TEST_F(SpidarDeviceTest, DestructionLeavesMinimumTension) {
  CalibrateAtHome();
  Run(100, Wrench{Vec3(-1.5, 0.0, 0.0), Vec3::Zero()});
  EXPECT_NE(emu_->Snapshot().last_command, MinDigits());
  dev_.reset();
  EXPECT_EQ(emu_->Snapshot().last_command, MinDigits());
}

TEST_F(SpidarDeviceTest, LostBoardIsAProtocolFault) {
  CalibrateAtHome();
  emu_->Stop();  // the board stops answering
  Status s = dev_->Exchange(kDt);
  EXPECT_FALSE(s.ok());
  EXPECT_TRUE(dev_->status().faults & kFaultProtocol);
  EXPECT_EQ(dev_->status().protocol_errors, 1u);
}

// The mode rheod uses: the emulator's physics follows the wall clock. The loop here runs as fast
// as the pty allows until 0.4 s of emulated time have passed.
TEST(SpidarEmulatorRealTime, DriverTracksAHeldGrip) {
  SpidarConfig config = testutil::LoadFrame("x5");
  auto emu = SpidarEmulator::Start(config, EmulatorOptions{});
  ASSERT_TRUE(emu.ok()) << emu.error().message;
  auto dev = OpenSpidarG(config, (*emu)->pty_path(), {.reply_timeout_us = 200'000});
  ASSERT_TRUE(dev.ok()) << dev.error().message;
  ASSERT_TRUE((*dev)->Calibrate().ok());
  const Pose at_calibration = (*emu)->Snapshot().pose;
  Pose target;
  target.position = Vec3(-0.02, 0.015, 0.01);
  (*emu)->HoldHand(target);
  const double start = (*emu)->Snapshot().time;
  int ticks = 0;
  while ((*emu)->Snapshot().time < start + 0.4 && ticks < 100000) {
    Status s = (*dev)->Exchange(kDt);
    ASSERT_TRUE(s.ok()) << s.error().message;
    (*dev)->SetWrench(Wrench());
    ++ticks;
  }
  ASSERT_TRUE((*dev)->Exchange(kDt).ok());
  const GripSnapshot s = (*emu)->Snapshot();
  EXPECT_LT((s.pose.position - target.position).norm(), 1e-3);
  EXPECT_LT(((*dev)->state().pose.position - (s.pose.position - at_calibration.position)).norm(),
            0.2e-3);
  EXPECT_EQ(s.protocol_errors, 0u);
}

}  // namespace
}  // namespace rheo::drivers
