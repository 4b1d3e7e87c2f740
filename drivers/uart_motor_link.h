// MotorLink over the open UART motor boards (one or more boards on one serial line).
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "drivers/transport.h"
#include "drivers/uart_protocol.h"

namespace rheo::drivers {

/// Asks each board of `board_ids` (in order) for its board-info over `transport` and checks they
/// drive `num_motors` motors in all. Opening a link does this; so does reopening a line.
Result<std::vector<uart::BoardInfo>> IdentifyUartBoards(ByteTransport& transport,
                                                        const std::vector<int>& board_ids,
                                                        int num_motors);

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
  LineStats line_stats() const override;

  /// From now on a line that fails as gone (kUnavailable: EIO, a hang-up) is handed to `source`,
  /// and while there is none every call fails at once (no I/O, no wait) until `source` offers a
  /// reopened one, which the next call takes. The counters' unwrapping carries on across the
  /// new line: the boards kept their power (a USB serial adapter was pulled out, not the boards'
  /// supply). Call after Open(), before the link is shared with other threads.
  void SetLineSource(std::unique_ptr<LineSource> source);

  /// Boards found by Open(), in motor order.
  const std::vector<uart::BoardInfo>& boards() const { return boards_; }

 private:
  // Collects (and drops) a reply still outstanding, takes a reopened line when there is none,
  // then discards input after a failure. Fails when there is no line.
  Status Prepare();
  // `s` from the transport: a line that failed as gone goes back to source_.
  Status Watch(Status s);
  Status WriteCommand(const uart::BoardInfo& board, std::span<const int16_t> command);
  // Reads one board's reply into counts[first_motor...]; a failure sets resync_.
  Status ReadCounts(const uart::BoardInfo& board, size_t first_motor, std::span<int64_t> counts);

  std::unique_ptr<ByteTransport> transport_;  // null while the line is away (source_ only)
  std::unique_ptr<LineSource> source_;        // null: the line is never reopened
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
