#include "drivers/uart_motor_link.h"

namespace rheo::drivers {

UartMotorLink::UartMotorLink(std::unique_ptr<ByteTransport> transport, std::vector<int> board_ids,
                             int reply_timeout_us)
    : transport_(std::move(transport)),
      board_ids_(std::move(board_ids)),
      reply_timeout_us_(reply_timeout_us) {}

Status UartMotorLink::Open(int num_motors) {
  boards_.clear();
  int motors = 0;
  for (int id : board_ids_) {
    std::array<uint8_t, uart::kBoardInfoRequestSize> request;
    uart::EncodeBoardInfoRequest(id, request);
    transport_->DiscardInput();
    if (Status s = transport_->Write(request, 100'000); !s.ok()) return s;
    std::array<uint8_t, uart::kBoardInfoReplySize> reply;
    Status r = transport_->ReadExact(reply, 2 * uart::kReplyWaitMs * 1000);
    if (!r.ok()) {
      return Error{ErrorCode::kUnavailable,
                   "UART motor board " + std::to_string(id) +
                       " did not answer board-info (check the cable, the board id and power): " +
                       r.error().message};
    }
    auto info = uart::DecodeBoardInfoReply(reply, id);
    if (!info.ok()) return info.error();
    boards_.push_back(*info);
    motors += info->n_motor;
  }
  if (motors != num_motors) {
    return Error{ErrorCode::kFailedPrecondition,
                 "UART motor boards drive " + std::to_string(motors) + " motors, the device has " +
                     std::to_string(num_motors)};
  }
  for (auto& u : unwrap_) u.Reset();
  model_ = "open UART motor board";
  for (const auto& b : boards_) {
    model_ += " #" + std::to_string(b.board_id) + " (model " + std::to_string(b.model) + ", " +
              std::to_string(b.n_motor) + " motors)";
  }
  return Status::Ok();
}

Status UartMotorLink::Exchange(std::span<const int16_t> command, std::span<int64_t> counts,
                               uint32_t* buttons) {
  // A reply that missed its deadline may still arrive: drop it before asking again.
  if (resync_) {
    transport_->DiscardInput();
    resync_ = false;
  }
  std::array<uint8_t, uart::kMaxFrameSize> frame;
  size_t motor = 0;
  for (const uart::BoardInfo& b : boards_) {
    const size_t n = uart::EncodeCurrentCommand(
        b.board_id, command.subspan(motor, static_cast<size_t>(b.n_motor)), frame);
    if (Status s = transport_->Write(std::span(frame.data(), n), reply_timeout_us_); !s.ok()) {
      return s;
    }
    const size_t reply_size = uart::CurrentReplySize(b.n_motor, b.n_force);
    if (Status s = transport_->ReadExact(std::span(frame.data(), reply_size), reply_timeout_us_);
        !s.ok()) {
      resync_ = true;
      return s;
    }
    uart::SensorReply reply;
    if (Status s = uart::DecodeCurrentReply(std::span(frame.data(), reply_size), b, &reply);
        !s.ok()) {
      resync_ = true;
      return s;
    }
    for (int i = 0; i < b.n_motor; ++i, ++motor) {
      counts[motor] = unwrap_[motor].Update(static_cast<uint16_t>(reply.position[i]));
    }
  }
  // The published reply carries no button bits.
  *buttons = 0;
  return Status::Ok();
}

}  // namespace rheo::drivers
