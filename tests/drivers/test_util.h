// Shared helpers for the driver tests: config loading and random poses in a frame's workspace.
#pragma once

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "drivers/spidar_config.h"
#include "drivers/spidar_kinematics.h"

namespace rheo::drivers::testutil {

inline const char* const kFrames[] = {"x3", "x4", "x5", "g6x"};

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline std::string FramePath(const std::string& frame) {
  return std::string(RHEO_DRIVERS_CONFIG_DIR) + "/spidar_g_" + frame + ".json";
}

inline SpidarConfig LoadFrame(const std::string& frame) {
  std::string text = ReadText(FramePath(frame));
  auto c = ParseSpidarConfig(text, FramePath(frame));
  EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().message);
  return c.ok() ? c.value() : SpidarConfig();
}

/// Uniform position in the workspace box, rotation by a uniform angle up to `max_tilt` about a
/// uniform random axis.
inline Pose RandomPose(const SpidarConfig& c, std::mt19937_64& rng, double fraction = 1.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Pose p;
  for (int k = 0; k < 3; ++k) p.position[k] = fraction * c.workspace.half_extent[k] * u(rng);
  Vec3 axis;
  do {
    axis = Vec3(u(rng), u(rng), u(rng));
  } while (axis.norm() < 0.1 || axis.norm() > 1.0);
  double angle = fraction * c.workspace.max_tilt * 0.5 * (u(rng) + 1.0);
  p.orientation = Eigen::AngleAxisd(angle, axis.normalized());
  return p;
}

inline double AngleBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b);
}

}  // namespace rheo::drivers::testutil
