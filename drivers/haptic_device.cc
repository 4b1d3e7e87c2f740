#include "drivers/haptic_device.h"

namespace rheo::drivers {

std::string FaultNames(uint32_t faults) {
  static constexpr std::pair<uint32_t, const char*> kNames[] = {
      {kFaultNotConnected, "not-connected"},
      {kFaultProtocol, "protocol"},
      {kFaultNotCalibrated, "not-calibrated"},
      {kFaultZeroLength, "zero-length"},
      {kFaultSlackString, "slack-string"},
      {kFaultWorkspace, "workspace"},
      {kFaultSolver, "solver"},
      {kFaultSafeStop, "safe-stop"},
  };
  std::string out;
  for (const auto& [bit, name] : kNames) {
    if (faults & bit) {
      if (!out.empty()) out += ",";
      out += name;
    }
  }
  return out;
}

}  // namespace rheo::drivers
