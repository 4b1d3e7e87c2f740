// The SPIDAR-G driver end to end: termios transport, UART board protocol, pose solver and QP
// against the emulator on a pseudo-terminal (lockstep: 1 ms of physics per exchange).
#include <gtest/gtest.h>

#include <filesystem>
#include <thread>
#include <vector>

#include "alloc_counter.h"
#include "common/clock.h"
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

// The line a USB serial adapter gives, pulled out and plugged in again: the emulator closes its
// end (the driver's reads see a hang-up, its writes EIO) and comes back on a new pty behind the
// same name. The driver reports the loss at once, every exchange then fails without waiting on
// the line, its reopener thread tries with a growing backoff, and after the replug the boards
// are identified again, the first command on the new line is minimum tension, and force comes
// back through the rate limiter (a ramp from zero).
TEST(SpidarLineReopen, AnUnpluggedLineIsReopenedWithAGrowingBackoff) {
  const SpidarConfig config = testutil::LoadFrame("x5");
  EmulatorOptions opt;
  opt.lockstep = true;
  auto started = SpidarEmulator::Start(config, opt);
  ASSERT_TRUE(started.ok()) << started.error().message;
  SpidarEmulator& emu = **started;
  SpidarOpenOptions oo;
  oo.reply_timeout_us = 200'000;  // a wait on a reply would show in the timings below
  oo.reopen_options.first_backoff_ns = 20'000'000;
  oo.reopen_options.max_backoff_ns = 160'000'000;
  auto opened = OpenSpidarG(config, emu.line_path(), oo);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  SpidarG& dev = **opened;
  for (int k = 0; k < 300; ++k) ASSERT_TRUE(dev.Exchange(kDt).ok());  // the grip settles
  ASSERT_TRUE(dev.Calibrate().ok());
  const Wrench push{Vec3(0.0, 0.0, 2.0), Vec3::Zero()};
  for (int k = 0; k < 50; ++k) {
    ASSERT_TRUE(dev.Exchange(kDt).ok());
    dev.SetWrench(push);
  }
  std::array<int16_t, 8> min_digits;
  for (int i = 0; i < 8; ++i) {
    const auto& s = config.strings[i];
    min_digits[i] = static_cast<int16_t>(std::lround(
        s.command_sign * s.min_tension * s.volts_per_newton * config.board.digits_per_volt));
  }
  ASSERT_NE(emu.Snapshot().last_command, min_digits);
  const uint64_t enumerations = emu.Snapshot().enumerations;

  ASSERT_TRUE(emu.Unplug().ok());
  EXPECT_FALSE(std::filesystem::exists(emu.line_path()));
  EXPECT_EQ(emu.pty_path(), "");
  Status lost = dev.Exchange(kDt);
  ASSERT_FALSE(lost.ok());
  EXPECT_EQ(lost.error().code, ErrorCode::kUnavailable) << lost.error().message;
  EXPECT_FALSE(dev.status().connected);
  EXPECT_TRUE(dev.status().faults & kFaultNotConnected);
  EXPECT_FALSE(dev.status().line.up);
  EXPECT_EQ(dev.status().line.losses, 1u);
  EXPECT_GT(dev.status().line.down_since_ns, 0);
  // Nothing to display: minimum tension, no wrench, whatever is asked.
  dev.SetWrench(push);
  EXPECT_EQ(dev.status().requested.force.norm(), 0.0);
  for (int i = 0; i < 8; ++i)
    EXPECT_NEAR(dev.status().tensions[i], config.strings[i].min_tension, 1e-12);

  // Exchanging every millisecond, as the loop does, while the reopener tries: each exchange
  // fails at once (no I/O), and the attempts come further and further apart.
  std::vector<int64_t> attempt_ns;
  int64_t slowest_ns = 0;
  uint64_t seen = dev.status().line.attempts;
  const int64_t give_up = MonotonicNowNs() + 10'000'000'000;
  while (attempt_ns.size() < 5 && MonotonicNowNs() < give_up) {
    const int64_t t0 = MonotonicNowNs();
    EXPECT_FALSE(dev.Exchange(kDt).ok());
    dev.SetWrench(push);
    EXPECT_FALSE(dev.Post().ok());
    const int64_t t1 = MonotonicNowNs();
    slowest_ns = std::max(slowest_ns, t1 - t0);
    const LineStats& line = dev.status().line;
    EXPECT_LE(line.backoff_ns, oo.reopen_options.max_backoff_ns);
    if (line.attempts != seen) {
      seen = line.attempts;
      attempt_ns.push_back(t1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(attempt_ns.size(), 5u) << "the reopener made " << attempt_ns.size() << " attempts";
  // An exchange that waited on the line would take a reply timeout (200 ms).
  EXPECT_LT(slowest_ns, 50'000'000)
      << "an exchange with the line away took " << slowest_ns * 1e-6 << " ms";
  std::vector<double> gaps_ms;
  for (size_t k = 1; k < attempt_ns.size(); ++k)
    gaps_ms.push_back((attempt_ns[k] - attempt_ns[k - 1]) * 1e-6);
  // Nominal 40, 80, 160, 160 ms (doubling from 20 ms to the 160 ms cap). A late wake-up can only
  // lengthen a gap, so the lower bounds are firm and the growth is checked with room to spare.
  EXPECT_GT(gaps_ms[0], 0.8 * 40);
  EXPECT_GT(gaps_ms[1], 0.8 * 80);
  EXPECT_GT(gaps_ms[2], 0.8 * 160);
  EXPECT_GT(gaps_ms[1], 1.2 * gaps_ms[0]);
  EXPECT_GT(gaps_ms[2], 1.2 * gaps_ms[1]);
  EXPECT_EQ(dev.status().line.backoff_ns, oo.reopen_options.max_backoff_ns);
  EXPECT_EQ(dev.status().line.reopens, 0u);
  std::printf(
      "attempt gaps %.1f, %.1f, %.1f, %.1f ms (nominal 40, 80, 160, 160); slowest "
      "exchange while away %.3f ms\n",
      gaps_ms[0], gaps_ms[1], gaps_ms[2], gaps_ms[3], slowest_ns * 1e-6);

  ASSERT_TRUE(emu.Replug().ok());
  EXPECT_TRUE(std::filesystem::exists(emu.line_path()));
  const int64_t replugged = MonotonicNowNs();
  Status back = Error{ErrorCode::kUnavailable, "not yet"};
  while (!back.ok() && MonotonicNowNs() < replugged + 5'000'000'000) {
    back = dev.Exchange(kDt);
    dev.SetWrench(push);
    if (!back.ok()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_TRUE(back.ok()) << back.error().message;
  const double back_ms = (MonotonicNowNs() - replugged) * 1e-6;
  EXPECT_TRUE(dev.status().connected);
  EXPECT_TRUE(dev.status().line.up);
  EXPECT_EQ(dev.status().line.reopens, 1u);
  EXPECT_EQ(dev.status().line.backoff_ns, 0);
  EXPECT_EQ(dev.status().line.down_since_ns, 0);
  GripSnapshot g = emu.Snapshot();
  EXPECT_EQ(g.replugs, 1u);
  EXPECT_EQ(g.enumerations, enumerations + 1) << "the board was not identified again";
  ASSERT_GE(g.commands_on_line, 1u);
  EXPECT_EQ(g.first_command_on_line, min_digits);
  // The loss stays latched (minimum tension) until it is cleared, as the daemon's loop does after
  // enough good exchanges.
  EXPECT_TRUE(dev.status().faults & kFaultNotConnected);
  for (int k = 0; k < 20; ++k) {
    ASSERT_TRUE(dev.Exchange(kDt).ok());
    dev.SetWrench(push);
  }
  EXPECT_EQ(emu.Snapshot().last_command, min_digits);
  dev.ClearFaults();
  ASSERT_TRUE(dev.Exchange(kDt).ok());
  dev.SetWrench(push);
  EXPECT_EQ(dev.status().faults, 0u);
  // The rate limiter starts from zero: one tick of 2000 N/s allows 1/1000 of it.
  EXPECT_NEAR(dev.status().requested.force.norm(), config.limits.max_force_rate * kDt, 1e-9);
  for (int k = 0; k < 5; ++k) {
    ASSERT_TRUE(dev.Exchange(kDt).ok());
    dev.SetWrench(push);
  }
  EXPECT_NEAR(dev.status().requested.force.z(), 2.0, 1e-9);
  EXPECT_NE(emu.Snapshot().last_command, min_digits);
  std::printf("back %.1f ms after the replug, %llu attempts in all\n", back_ms,
              static_cast<unsigned long long>(dev.status().line.attempts));
}

// Whatever answers behind the name after a replug must be the boards the device was opened with:
// an emulator of another model there is refused, attempt after attempt, and the line stays away
// until the right board is back.
TEST(SpidarLineReopen, AnotherBoardBehindTheNameIsRefused) {
  const SpidarConfig config = testutil::LoadFrame("x5");
  EmulatorOptions opt;
  opt.lockstep = true;
  auto first = SpidarEmulator::Start(config, opt);
  ASSERT_TRUE(first.ok()) << first.error().message;
  SpidarOpenOptions oo;
  oo.reply_timeout_us = 200'000;
  oo.reopen_options.first_backoff_ns = 10'000'000;
  oo.reopen_options.max_backoff_ns = 40'000'000;
  auto opened = OpenSpidarG(config, (*first)->line_path(), oo);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  SpidarG& dev = **opened;
  ASSERT_TRUE(dev.Exchange(kDt).ok());
  ASSERT_TRUE((*first)->Unplug().ok());
  EXPECT_FALSE(dev.Exchange(kDt).ok());

  EmulatorOptions other = opt;
  other.model = 5;
  other.line_path = (*first)->line_path();
  auto second = SpidarEmulator::Start(config, other);
  ASSERT_TRUE(second.ok()) << second.error().message;
  const int64_t give_up = MonotonicNowNs() + 10'000'000'000;
  while (((*second)->Snapshot().enumerations < 2 || dev.status().line.attempts < 2) &&
         MonotonicNowNs() < give_up) {
    EXPECT_FALSE(dev.Exchange(kDt).ok());
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_GE((*second)->Snapshot().enumerations, 2u) << "the other board was not asked";
  EXPECT_EQ((*second)->Snapshot().current_commands, 0u) << "the other board got commands";
  EXPECT_EQ(dev.status().line.reopens, 0u);
  EXPECT_FALSE(dev.status().connected);

  second->reset();  // its name goes with it
  ASSERT_TRUE((*first)->Replug().ok());
  Status back = Error{ErrorCode::kUnavailable, "not yet"};
  while (!back.ok() && MonotonicNowNs() < give_up) {
    back = dev.Exchange(kDt);
    if (!back.ok()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(dev.status().line.reopens, 1u);
  EXPECT_TRUE(dev.status().connected);
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
