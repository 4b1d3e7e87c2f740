#include "drivers/spidar_config.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "test_util.h"

namespace rheo::drivers {
namespace {

using testutil::FramePath;
using testutil::kFrames;
using testutil::ReadText;

TEST(SpidarConfig, EveryShippedFrameParses) {
  for (const char* frame : kFrames) {
    std::string text = ReadText(FramePath(frame));
    ASSERT_FALSE(text.empty()) << FramePath(frame);
    auto c = ParseSpidarConfig(text, FramePath(frame));
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_FALSE(c->name.empty());
    for (const SpidarString& s : c->strings) {
      EXPECT_GT(s.min_tension, 0.0);
      EXPECT_GT(s.max_tension, s.min_tension);
    }
  }
}

// The X3 table in the reference gives the home lengths: 103.8 mm and 100.3 mm.
TEST(SpidarConfig, X3HomeLengthsMatchThePublishedTable) {
  SpidarConfig c = testutil::LoadFrame("x3");
  const double expected[8] = {103.8, 103.8, 100.3, 100.3, 103.8, 103.8, 100.3, 100.3};
  for (int i = 0; i < 8; ++i) {
    double len = (c.strings[i].motor_exit - c.strings[i].grip_point).norm() * 1e3;
    EXPECT_NEAR(len, expected[i], 0.15) << "string " << i;
  }
  EXPECT_NEAR(c.strings[0].metres_per_count, 1.66555e-5, 1e-12);
  EXPECT_LT(c.strings[2].metres_per_count, 0.0);  // sign flipped on motors 2-5
  EXPECT_LT(c.strings[5].metres_per_count, 0.0);
  EXPECT_GT(c.strings[6].metres_per_count, 0.0);
  EXPECT_DOUBLE_EQ(c.strings[0].volts_per_newton, 0.3653);
  EXPECT_DOUBLE_EQ(c.strings[0].min_tension, 0.3);
  EXPECT_DOUBLE_EQ(c.strings[0].max_tension, 20.0);
}

nlohmann::json X5Json() {
  return nlohmann::json::parse(ReadText(FramePath("x5")));
}

std::string ErrorOf(const nlohmann::json& j) {
  auto c = ParseSpidarConfig(j.dump(), "test.json");
  EXPECT_FALSE(c.ok());
  return c.ok() ? "" : c.error().message;
}

// The "haptics" block is read with the rest of the frame file (rheod does not parse it again).
TEST(SpidarConfig, MechanismDampingComesFromTheHapticsBlock) {
  auto j = X5Json();
  auto c = ParseSpidarConfig(j.dump(), "test.json");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_DOUBLE_EQ(c->mechanism.damping, j["haptics"]["device_damping_n_s_per_m"].get<double>());
  j["haptics"]["device_damping_n_s_per_m"] = 3.5;
  EXPECT_DOUBLE_EQ(ParseSpidarConfig(j.dump(), "test.json")->mechanism.damping, 3.5);
  j.erase("haptics");
  EXPECT_DOUBLE_EQ(ParseSpidarConfig(j.dump(), "test.json")->mechanism.damping, 2.0);
}

TEST(SpidarConfig, ErrorsNameTheField) {
  {
    auto j = X5Json();
    j["haptics"]["device_damping_n_s_per_m"] = 0.0;
    EXPECT_NE(ErrorOf(j).find("haptics.device_damping_n_s_per_m: must be in (0"),
              std::string::npos);
  }
  {
    auto j = X5Json();
    j["strings"][3].erase("min_tension_n");
    EXPECT_EQ(ErrorOf(j), "test.json: strings[3].min_tension_n: missing");
  }
  {
    auto j = X5Json();
    j["strings"][5]["min_tension_n"] = -1.0;
    EXPECT_NE(ErrorOf(j).find("strings[5].min_tension_n: must be in (0"), std::string::npos);
  }
  {
    auto j = X5Json();
    j["strings"][2]["max_tension_n"] = 0.1;  // below min 0.3
    EXPECT_NE(ErrorOf(j).find("strings[2].max_tension_n: must exceed"), std::string::npos);
  }
  {
    auto j = X5Json();
    j["strings"][1]["motor_exit_m"] = {0.1, 0.2};
    EXPECT_EQ(ErrorOf(j), "test.json: strings[1].motor_exit_m: expected an array of 3 numbers");
  }
  {
    auto j = X5Json();
    j["strings"][0]["grip_point_m"][2] = "x";
    EXPECT_EQ(ErrorOf(j), "test.json: strings[0].grip_point_m[2]: expected a number");
  }
  {
    auto j = X5Json();
    j["strings"].erase(7);
    EXPECT_NE(ErrorOf(j).find("strings: expected an array of 8 strings (got 7)"),
              std::string::npos);
  }
  {
    auto j = X5Json();
    j["board"]["type"] = "can";
    EXPECT_NE(ErrorOf(j).find("board.type: expected \"uart\" or \"sh4\""), std::string::npos);
  }
  {
    auto j = X5Json();
    j["board"]["board_ids"] = {9};
    EXPECT_NE(ErrorOf(j).find("board.board_ids[0]"), std::string::npos);
  }
  {
    auto j = X5Json();
    j["pose_solver"]["iterations"] = 0;
    EXPECT_NE(ErrorOf(j).find("pose_solver.iterations: must be in [1, 20]"), std::string::npos);
  }
  {
    auto j = X5Json();
    j["strings"][4]["metres_per_count"] = 0.0;
    EXPECT_NE(ErrorOf(j).find("strings[4].metres_per_count: must not be 0"), std::string::npos);
  }
  {
    auto j = X5Json();
    j["workspace"]["half_extent_m"] = {0.3, 0.3, 0.3};  // beyond the motors
    EXPECT_NE(ErrorOf(j).find("workspace: at corner"), std::string::npos);
  }
  {
    auto j = X5Json();
    j.erase("limits");
    EXPECT_EQ(ErrorOf(j), "test.json: limits: missing");
  }
  EXPECT_NE(ParseSpidarConfig("{\"name\": ", "broken.json")
                .error()
                .message.find("broken.json: not valid JSON"),
            std::string::npos);
}

}  // namespace
}  // namespace rheo::drivers
