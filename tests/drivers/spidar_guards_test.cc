// SpidarG guards that the emulator cannot provoke physically (a slipped string, a string wound
// to zero length), through an in-memory board that turns a pose into encoder counts.
#include <gtest/gtest.h>

#include "alloc_counter.h"
#include "drivers/spidar_g.h"
#include "test_util.h"

namespace rheo::drivers {
namespace {

class PoseBoard final : public MotorLink {
 public:
  explicit PoseBoard(const SpidarConfig& c) : c_(c) { ComputeStringGeometry(c_, Pose(), &home_); }
  Pose pose;
  StringVector extra = StringVector::Zero();  // added to the true lengths [m]
  std::array<int16_t, 8> last{};
  Status Open(int n) override {
    return n == 8 ? Status::Ok() : Status(InvalidArgument("8 motors"));
  }
  const char* model() const override { return "pose board"; }
  int max_command() const override { return 4095; }
  Status Exchange(std::span<const int16_t> command, std::span<int64_t> counts,
                  uint32_t* buttons) override {
    std::copy(command.begin(), command.end(), last.begin());
    StringGeometry g;
    ComputeStringGeometry(c_, pose, &g);
    for (int i = 0; i < 8; ++i) {
      counts[i] =
          std::llround((g.length[i] + extra[i] - home_.length[i]) / c_.strings[i].metres_per_count);
    }
    *buttons = 0;
    return Status::Ok();
  }

 private:
  SpidarConfig c_;
  StringGeometry home_;
};

class SpidarGuardsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    config_ = testutil::LoadFrame("x3");
    auto b = std::make_unique<PoseBoard>(config_);
    board_ = b.get();
    dev_ = std::make_unique<SpidarG>(config_, std::move(b));
    ASSERT_TRUE(dev_->Open().ok());
    ASSERT_TRUE(dev_->Calibrate().ok());
    min_ = board_->last;
  }
  void Tick(const Wrench& w) {
    ASSERT_TRUE(dev_->Exchange(1e-3).ok());
    dev_->SetWrench(w);
  }
  SpidarConfig config_;
  PoseBoard* board_ = nullptr;
  std::unique_ptr<SpidarG> dev_;
  std::array<int16_t, 8> min_{};
  const Wrench push_{Vec3(0.0, 0.0, 1.0), Vec3::Zero()};
};

TEST_F(SpidarGuardsTest, SlackStringIsTransient) {
  for (int k = 0; k < 20; ++k) Tick(push_);
  EXPECT_EQ(dev_->status().faults, kFaultNone);
  EXPECT_NE(board_->last, min_);
  board_->extra[3] = 0.03;  // string 3 slipped: 30 mm more than any pose explains
  for (int k = 0; k < 5; ++k) Tick(push_);
  EXPECT_TRUE(dev_->status().faults & kFaultSlackString);
  Tick(push_);
  EXPECT_EQ(board_->last, min_);
  board_->extra[3] = 0.0;  // re-wound
  for (int k = 0; k < 20; ++k) Tick(push_);
  EXPECT_EQ(dev_->status().faults, kFaultNone) << FaultNames(dev_->status().faults);
  EXPECT_NE(board_->last, min_);
}

TEST_F(SpidarGuardsTest, ZeroLengthIsLatchedUntilCleared) {
  for (int k = 0; k < 5; ++k) Tick(push_);
  // String 0 reads almost nothing: its length falls below the guard.
  board_->extra[0] =
      -(config_.strings[0].motor_exit - config_.strings[0].grip_point).norm() + 0.002;
  Tick(push_);
  EXPECT_TRUE(dev_->status().faults & kFaultZeroLength);
  const Pose frozen = dev_->state().pose;
  board_->extra[0] = 0.0;
  for (int k = 0; k < 5; ++k) Tick(push_);
  Tick(push_);
  EXPECT_TRUE(dev_->status().faults & kFaultZeroLength);  // latched
  EXPECT_EQ(board_->last, min_);
  EXPECT_TRUE(dev_->state().pose.position.isApprox(frozen.position) ||
              dev_->state().pose.position.norm() < 1e-6);
  dev_->ClearFaults();
  for (int k = 0; k < 5; ++k) Tick(push_);
  EXPECT_EQ(dev_->status().faults, kFaultNone) << FaultNames(dev_->status().faults);
}

TEST_F(SpidarGuardsTest, NonFiniteWrenchIsRefused) {
  Tick(Wrench{Vec3(NAN, 0, 0), Vec3::Zero()});
  Tick(Wrench{Vec3(NAN, 0, 0), Vec3::Zero()});
  EXPECT_EQ(board_->last, min_);
  EXPECT_TRUE(dev_->status().displayed.force.allFinite());
}

// The loop's calls must not touch the heap (Drake's LimitMalloc idea): a whole tick, moving,
// with a wrench that changes every tick, allocates nothing.
TEST_F(SpidarGuardsTest, TickAllocatesNothing) {
  Tick(push_);
  const long before = rheo::testing::ThreadAllocations();
  for (int k = 0; k < 1000; ++k) {
    board_->pose.position = Vec3(0.01 * std::sin(k * 0.01), 0.005 * std::cos(k * 0.02), 0.0);
    board_->pose.orientation = Eigen::AngleAxisd(0.2 * std::sin(k * 0.005), Vec3::UnitY());
    ASSERT_TRUE(dev_->Exchange(1e-3).ok());
    dev_->SetWrench(Wrench{Vec3(std::sin(k * 0.03), 0.5, -0.5), Vec3(0.0, 0.01, 0.0)});
  }
  EXPECT_EQ(rheo::testing::ThreadAllocations() - before, 0);
  {
    auto probe = std::make_unique<int>(1);  // the counter itself works
    EXPECT_EQ(*probe, 1);
  }
  EXPECT_EQ(rheo::testing::ThreadAllocations() - before, 1);
  EXPECT_EQ(dev_->status().faults, kFaultNone) << FaultNames(dev_->status().faults);
  EXPECT_NE(board_->last, min_);
}

}  // namespace
}  // namespace rheo::drivers
