// Wire format of the open UART motor boards (2 Mbit/s 8N1): a pure codec, bytes in, values out.
// The driver (uart_motor_link.h) and the emulator (spidar_emulator.h) both use it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "common/status.h"

namespace rheo::drivers::uart {

/// Command numbers; the header byte is (command << 3) | board_id.
enum class Command : uint8_t {
  kNone = 0,
  kBoardInfo = 1,
  kSetCommandLengths = 2,
  kAll = 3,
  kSensor = 4,
  kDirect = 5,
  kCurrent = 6,
  kInterpolate = 7,
  kForceControl = 8,
  kSetParameter = 9,
  kResetSensor = 10,
  kGetParameter = 11,
};

inline constexpr int kMaxBoards = 8;  // board ids 0-7
inline constexpr int kMaxMotorsPerBoard = 8;
inline constexpr int kMaxForcesPerBoard = 8;
inline constexpr int kEnumeratePreamble = 40;  // zero bytes that resynchronise every board
inline constexpr int kBoardInfoPadding = 26;   // zero bytes after the board-info header
inline constexpr int kBoardInfoRequestSize = kEnumeratePreamble + 1 + kBoardInfoPadding;
inline constexpr int kBoardInfoReplySize = 7;
inline constexpr int kReplyWaitMs = 10;        // boards answer board-info within this [ms]
inline constexpr int kMaxCommandValue = 4095;  // |current command| <= this (3.3 V full scale)
inline constexpr double kDigitsPerVolt = 4096.0 / 3.3;
inline constexpr int kMaxFrameSize = 1 + 2 * (2 * kMaxMotorsPerBoard + kMaxForcesPerBoard);

constexpr uint8_t Header(Command command, int board_id) {
  return static_cast<uint8_t>((static_cast<unsigned>(command) << 3) | (board_id & 7));
}
constexpr Command HeaderCommand(uint8_t header) {
  return static_cast<Command>(header >> 3);
}
constexpr int HeaderBoard(uint8_t header) {
  return header & 7;
}

/// What a board says about itself in reply to board-info.
struct BoardInfo {
  int board_id = 0;
  int model = 0;  // model 7: 8 motors, 4 force inputs
  int n_target = 0;
  int n_motor = 0;
  int n_current = 0;
  int n_force = 0;
  int n_touch = 0;
};

/// Enumeration request for one board: 40 zeros, header, 26 zeros. Returns bytes written;
/// `out` must hold kBoardInfoRequestSize.
size_t EncodeBoardInfoRequest(int board_id, std::span<uint8_t> out);
/// Board side: the 7-byte reply.
size_t EncodeBoardInfoReply(const BoardInfo& info, std::span<uint8_t> out);
/// Parses a board-info reply; checks the header names `expected_board` and the counts fit.
Result<BoardInfo> DecodeBoardInfoReply(std::span<const uint8_t> in, int expected_board);

/// Size of a "current" command for n motors: header + n int16.
constexpr size_t CurrentCommandSize(int n_motor) {
  return 1 + 2 * static_cast<size_t>(n_motor);
}
/// Size of the reply: header + positions, velocities (n_motor int16 each) + forces (n_force).
constexpr size_t CurrentReplySize(int n_motor, int n_force) {
  return 1 + 2 * (2 * static_cast<size_t>(n_motor) + static_cast<size_t>(n_force));
}

/// Encodes "current": values are clamped to +-kMaxCommandValue. Returns bytes written.
size_t EncodeCurrentCommand(int board_id, std::span<const int16_t> values, std::span<uint8_t> out);
/// Board side: reads the values of a complete "current" command (header included).
Status DecodeCurrentCommand(std::span<const uint8_t> in, int n_motor, std::span<int16_t> values);

/// Sensor values in a "current" reply (raw: positions wrap at 16 bits).
struct SensorReply {
  std::array<int16_t, kMaxMotorsPerBoard> position{};  // encoder counts, wrapping
  std::array<int16_t, kMaxMotorsPerBoard> velocity{};  // board units
  std::array<int16_t, kMaxForcesPerBoard> force{};     // ADC digits
};
size_t EncodeCurrentReply(int board_id, const BoardInfo& info, const SensorReply& reply,
                          std::span<uint8_t> out);
Status DecodeCurrentReply(std::span<const uint8_t> in, const BoardInfo& info, SensorReply* out);

/// Turns a wrapping 16-bit counter into a continuous count: each step is taken as the shortest
/// signed difference, so it is correct while the counter moves less than 32767 counts per read.
class CounterUnwrapper {
 public:
  void Reset() { started_ = false; }
  int64_t Update(uint16_t raw) {
    if (!started_) {
      started_ = true;
      total_ = static_cast<int16_t>(raw);
    } else {
      total_ += static_cast<int16_t>(static_cast<uint16_t>(raw - last_));
    }
    last_ = raw;
    return total_;
  }
  int64_t value() const { return total_; }

 private:
  bool started_ = false;
  uint16_t last_ = 0;
  int64_t total_ = 0;
};

}  // namespace rheo::drivers::uart
