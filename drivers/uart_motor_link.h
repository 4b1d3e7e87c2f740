// MotorLink over the open UART motor boards (one or more boards on one serial line).
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "drivers/transport.h"
#include "drivers/uart_protocol.h"

namespace rheo::drivers {

/// Drives the boards with `board_ids` (motor order follows the list) through `transport`.
class UartMotorLink final : public MotorLink {
 public:
  /// `reply_timeout_us` bounds each read of a per-tick reply [us].
  UartMotorLink(std::unique_ptr<ByteTransport> transport, std::vector<int> board_ids,
                int reply_timeout_us = 2000);

  Status Open(int num_motors) override;
  const char* model() const override { return model_.c_str(); }
  int max_command() const override { return uart::kMaxCommandValue; }
  Status Exchange(std::span<const int16_t> command, std::span<int64_t> counts,
                  uint32_t* buttons) override;
  /// Post() writes the command (boards before the last one are exchanged in full: they share
  /// the line) and leaves the last board's reply for Collect().
  bool can_post() const override { return true; }
  Status Post(std::span<const int16_t> command) override;
  Status Collect(std::span<int64_t> counts, uint32_t* buttons) override;
  bool posted() const override { return posted_; }

  /// Boards found by Open(), in motor order.
  const std::vector<uart::BoardInfo>& boards() const { return boards_; }

 private:
  // Collects (and drops) a reply still outstanding, then discards input after a failure.
  void Prepare();
  Status WriteCommand(const uart::BoardInfo& board, std::span<const int16_t> command);
  // Reads one board's reply into counts[first_motor...]; a failure sets resync_.
  Status ReadCounts(const uart::BoardInfo& board, size_t first_motor, std::span<int64_t> counts);

  std::unique_ptr<ByteTransport> transport_;
  std::vector<int> board_ids_;
  int reply_timeout_us_;
  std::vector<uart::BoardInfo> boards_;
  std::array<uart::CounterUnwrapper, uart::kMaxBoards * uart::kMaxMotorsPerBoard> unwrap_;
  std::string model_ = "UART motor boards (not opened)";
  bool resync_ = false;  // the last exchange failed: discard input first
  bool posted_ = false;  // the last board's reply to a Post() is outstanding
  // Counts of the boards Post() exchanged in full (all but the last), and scratch for a dropped
  // reply.
  std::array<int64_t, uart::kMaxBoards * uart::kMaxMotorsPerBoard> posted_counts_{};
};

}  // namespace rheo::drivers
