// What the daemon calls to get a SPIDAR-G: load a frame file, open the controller it names.
#pragma once

#include <memory>
#include <string>

#include "drivers/line_reopener.h"
#include "drivers/spidar_config.h"
#include "drivers/spidar_g.h"

namespace rheo::drivers {

/// Reads and parses a frame layout file (drivers/config/spidar_g_*.json).
Result<SpidarConfig> LoadSpidarConfigFile(const std::string& path);

struct SpidarOpenOptions {
  /// Longest wait for a board's reply in an exchange [us]. 2 ms suits a real board on a
  /// dedicated serial line; an emulator on a busy machine may need more.
  int reply_timeout_us = 2000;
  /// UART boards: a serial line that goes away later (EIO, a hang-up: a USB serial adapter
  /// pulled out) is reopened at `port` on a thread of its own, with this backoff, and the boards
  /// on it identified again before the device uses it (LineReopener). `port` should then be a
  /// stable name (/dev/serial/by-id/..., SpidarEmulator::line_path()): the adapter comes back
  /// as another ttyUSB. false: a lost line stays lost.
  bool reopen = true;
  ReopenOptions reopen_options{};
};

/// Builds a SPIDAR-G on the controller the config names and opens it (not yet calibrated).
/// UART boards: `port` is the serial device (e.g. /dev/ttyUSB0, or SpidarEmulator::line_path()).
/// SH4: `port` is ignored; the board is found by its USB id (unverified protocol).
Result<std::unique_ptr<SpidarG>> OpenSpidarG(const SpidarConfig& config, const std::string& port,
                                             const SpidarOpenOptions& options = {});

}  // namespace rheo::drivers
