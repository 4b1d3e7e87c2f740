#include "drivers/uart_motor_link.h"

namespace rheo::drivers {

UartMotorLink::UartMotorLink(std::unique_ptr<ByteTransport> transport, std::vector<int> board_ids,
                             int reply_timeout_us)
    : transport_(std::move(transport)),
      board_ids_(std::move(board_ids)),
      reply_timeout_us_(reply_timeout_us) {}

Result<std::vector<uart::BoardInfo>> IdentifyUartBoards(ByteTransport& transport,
                                                        const std::vector<int>& board_ids,
                                                        int num_motors) {
  std::vector<uart::BoardInfo> boards;
  int motors = 0;
  for (int id : board_ids) {
    std::array<uint8_t, uart::kBoardInfoRequestSize> request;
    uart::EncodeBoardInfoRequest(id, request);
    std::array<uint8_t, uart::kBoardInfoReplySize> reply;
    // Each try waits twice as long as the one before: 20, 40, 80 and 160 ms, 300 ms in all
    // before the board is declared absent. Three tries of 20 ms each had failed start-up on a
    // busy machine, where an emulated board's thread and the pty's delivery can both be late.
    constexpr int kTries = 4;
    Status r = Status::Ok();
    for (int attempt = 0; attempt < kTries; ++attempt) {
      const int window_us = (2 * uart::kReplyWaitMs * 1000) << attempt;
      transport.DiscardInput();
      if (Status s = transport.Write(request, 100'000); !s.ok()) return s.error();
      r = transport.ReadExact(reply, window_us);
      if (r.ok()) {
        // A late board answers every try it was sent: the reply just read may be an earlier
        // try's, and the later tries' replies are still coming. Left on the line, the next one
        // was read as the first current reply ("current reply header 8 is not board 0's": 8 is
        // board 0's board-info header), which failed start-up on a loaded machine. Each
        // earlier try's reply gets one window to arrive and is dropped; the first that does not
        // come ends the wait (the ones before it were discarded before a later try was sent).
        std::array<uint8_t, uart::kBoardInfoReplySize> late;
        for (int k = 0; k < attempt; ++k)
          if (!transport.ReadExact(late, window_us).ok()) break;
        transport.DiscardInput();
        break;
      }
    }
    if (!r.ok()) {
      return Error{ErrorCode::kUnavailable,
                   "UART motor board " + std::to_string(id) + " did not answer board-info in " +
                       std::to_string(kTries) +
                       " tries (check the cable, the board id and power): " + r.error().message};
    }
    auto info = uart::DecodeBoardInfoReply(reply, id);
    if (!info.ok()) return info.error();
    boards.push_back(*info);
    motors += info->n_motor;
  }
  if (motors != num_motors) {
    return Error{ErrorCode::kFailedPrecondition,
                 "UART motor boards drive " + std::to_string(motors) + " motors, the device has " +
                     std::to_string(num_motors)};
  }
  return boards;
}

Status UartMotorLink::Open(int num_motors) {
  boards_.clear();
  if (!transport_) return Error{ErrorCode::kUnavailable, "UART motor link: the line is away"};
  auto boards = IdentifyUartBoards(*transport_, board_ids_, num_motors);
  if (!boards.ok()) return boards.error();
  boards_ = std::move(boards).value();
  for (auto& u : unwrap_) u.Reset();
  posted_ = false;
  resync_ = false;
  model_ = "open UART motor board";
  for (const auto& b : boards_) {
    model_ += " #" + std::to_string(b.board_id) + " (model " + std::to_string(b.model) + ", " +
              std::to_string(b.n_motor) + " motors)";
  }
  return Status::Ok();
}

void UartMotorLink::SetLineSource(std::unique_ptr<LineSource> source) {
  source_ = std::move(source);
}

LineStats UartMotorLink::line_stats() const {
  LineStats s = source_ ? source_->stats() : LineStats{};
  s.up = transport_ != nullptr;
  return s;
}

Status UartMotorLink::Watch(Status s) {
  if (!s.ok() && s.error().code == ErrorCode::kUnavailable && source_ && transport_) {
    // Gone, not late: nothing more will arrive on this line. What was outstanding on it is lost
    // with it.
    source_->Lost(std::move(transport_));
    posted_ = false;
    resync_ = false;
  }
  return s;
}

Status UartMotorLink::WriteCommand(const uart::BoardInfo& board, std::span<const int16_t> command) {
  std::array<uint8_t, uart::kMaxFrameSize> frame;
  const size_t n = uart::EncodeCurrentCommand(board.board_id, command, frame);
  return Watch(transport_->Write(std::span(frame.data(), n), reply_timeout_us_));
}

Status UartMotorLink::ReadCounts(const uart::BoardInfo& board, size_t first_motor,
                                 std::span<int64_t> counts) {
  std::array<uint8_t, uart::kMaxFrameSize> frame;
  const size_t reply_size = uart::CurrentReplySize(board.n_motor, board.n_force);
  if (Status s = transport_->ReadExact(std::span(frame.data(), reply_size), reply_timeout_us_);
      !s.ok()) {
    resync_ = true;
    return Watch(std::move(s));
  }
  uart::SensorReply reply;
  if (Status s = uart::DecodeCurrentReply(std::span(frame.data(), reply_size), board, &reply);
      !s.ok()) {
    resync_ = true;
    return s;
  }
  for (int i = 0; i < board.n_motor; ++i) {
    const size_t m = first_motor + static_cast<size_t>(i);
    counts[m] = unwrap_[m].Update(static_cast<uint16_t>(reply.position[i]));
  }
  return Status::Ok();
}

Status UartMotorLink::Prepare() {
  // A posted reply nobody collected is read (keeping the counters' unwrapping continuous) and
  // dropped; one that does not come sets resync_.
  if (posted_) {
    uint32_t buttons = 0;
    (void)Collect(posted_counts_, &buttons);
  }
  if (!transport_) {
    if (source_) transport_ = source_->Take();
    // Short enough for std::string's inline buffer: while the line is away the loop gets this
    // every tick, and the loop does not allocate.
    if (!transport_) return Error{ErrorCode::kUnavailable, "no serial line"};
    posted_ = false;
    resync_ = false;
  }
  // A reply that missed its deadline may still arrive: drop it before asking again.
  if (resync_) {
    transport_->DiscardInput();
    resync_ = false;
  }
  return Status::Ok();
}

Status UartMotorLink::Exchange(std::span<const int16_t> command, std::span<int64_t> counts,
                               uint32_t* buttons) {
  if (Status s = Prepare(); !s.ok()) return s;
  size_t motor = 0;
  for (const uart::BoardInfo& b : boards_) {
    const auto n = static_cast<size_t>(b.n_motor);
    if (Status s = WriteCommand(b, command.subspan(motor, n)); !s.ok()) return s;
    if (Status s = ReadCounts(b, motor, counts); !s.ok()) return s;
    motor += n;
  }
  // The published reply carries no button bits.
  *buttons = 0;
  return Status::Ok();
}

Status UartMotorLink::Post(std::span<const int16_t> command) {
  if (boards_.empty()) return FailedPrecondition("UART motor link: Post() before Open()");
  if (Status s = Prepare(); !s.ok()) return s;
  // Boards share one line: all but the last answer before the next is addressed, so their
  // replies cannot overlap; only the last board's reply is left outstanding.
  size_t motor = 0;
  for (size_t k = 0; k + 1 < boards_.size(); ++k) {
    const uart::BoardInfo& b = boards_[k];
    const auto n = static_cast<size_t>(b.n_motor);
    if (Status s = WriteCommand(b, command.subspan(motor, n)); !s.ok()) return s;
    if (Status s = ReadCounts(b, motor, posted_counts_); !s.ok()) return s;
    motor += n;
  }
  const uart::BoardInfo& last = boards_.back();
  if (Status s = WriteCommand(last, command.subspan(motor, static_cast<size_t>(last.n_motor)));
      !s.ok()) {
    return s;
  }
  posted_ = true;
  return Status::Ok();
}

Status UartMotorLink::Collect(std::span<int64_t> counts, uint32_t* buttons) {
  if (!posted_) return FailedPrecondition("UART motor link: Collect() without a posted command");
  posted_ = false;
  size_t motor = 0;
  for (size_t k = 0; k + 1 < boards_.size(); ++k) {
    for (int i = 0; i < boards_[k].n_motor; ++i, ++motor) counts[motor] = posted_counts_[motor];
  }
  if (Status s = ReadCounts(boards_.back(), motor, counts); !s.ok()) return s;
  *buttons = 0;
  return Status::Ok();
}

}  // namespace rheo::drivers
