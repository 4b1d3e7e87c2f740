#include "drivers/uart_protocol.h"

#include <algorithm>
#include <cstring>
#include <string>

namespace rheo::drivers::uart {
namespace {

void PutInt16(uint8_t* p, int16_t v) {
  const auto u = static_cast<uint16_t>(v);
  p[0] = static_cast<uint8_t>(u & 0xFF);
  p[1] = static_cast<uint8_t>(u >> 8);
}
int16_t GetInt16(const uint8_t* p) {
  return static_cast<int16_t>(static_cast<uint16_t>(p[0] | (p[1] << 8)));
}

Error Malformed(const std::string& what) {
  return {ErrorCode::kUnavailable, "UART motor board: " + what};
}

}  // namespace

size_t EncodeBoardInfoRequest(int board_id, std::span<uint8_t> out) {
  if (out.size() < kBoardInfoRequestSize) return 0;
  std::memset(out.data(), 0, kBoardInfoRequestSize);
  out[kEnumeratePreamble] = Header(Command::kBoardInfo, board_id);
  return kBoardInfoRequestSize;
}

size_t EncodeBoardInfoReply(const BoardInfo& info, std::span<uint8_t> out) {
  if (out.size() < kBoardInfoReplySize) return 0;
  out[0] = Header(Command::kBoardInfo, info.board_id);
  out[1] = static_cast<uint8_t>(info.model);
  out[2] = static_cast<uint8_t>(info.n_target);
  out[3] = static_cast<uint8_t>(info.n_motor);
  out[4] = static_cast<uint8_t>(info.n_current);
  out[5] = static_cast<uint8_t>(info.n_force);
  out[6] = static_cast<uint8_t>(info.n_touch);
  return kBoardInfoReplySize;
}

Result<BoardInfo> DecodeBoardInfoReply(std::span<const uint8_t> in, int expected_board) {
  if (in.size() < kBoardInfoReplySize) {
    return Malformed("board-info reply of " + std::to_string(in.size()) + " bytes, expected " +
                     std::to_string(kBoardInfoReplySize));
  }
  if (in[0] != Header(Command::kBoardInfo, expected_board)) {
    return Malformed("board-info reply header " + std::to_string(in[0]) + " is not board " +
                     std::to_string(expected_board) + "'s");
  }
  BoardInfo info;
  info.board_id = expected_board;
  info.model = in[1];
  info.n_target = in[2];
  info.n_motor = in[3];
  info.n_current = in[4];
  info.n_force = in[5];
  info.n_touch = in[6];
  if (info.n_motor < 1 || info.n_motor > kMaxMotorsPerBoard) {
    return Malformed("board " + std::to_string(expected_board) + " reports " +
                     std::to_string(info.n_motor) + " motors (1-8 supported)");
  }
  if (info.n_force > kMaxForcesPerBoard) {
    return Malformed("board " + std::to_string(expected_board) + " reports " +
                     std::to_string(info.n_force) + " force inputs (at most 8 supported)");
  }
  return info;
}

size_t EncodeCurrentCommand(int board_id, std::span<const int16_t> values, std::span<uint8_t> out) {
  const size_t n = CurrentCommandSize(static_cast<int>(values.size()));
  if (out.size() < n) return 0;
  out[0] = Header(Command::kCurrent, board_id);
  for (size_t i = 0; i < values.size(); ++i) {
    const int v = std::clamp<int>(values[i], -kMaxCommandValue, kMaxCommandValue);
    PutInt16(&out[1 + 2 * i], static_cast<int16_t>(v));
  }
  return n;
}

Status DecodeCurrentCommand(std::span<const uint8_t> in, int n_motor, std::span<int16_t> values) {
  if (in.size() < CurrentCommandSize(n_motor) || values.size() < static_cast<size_t>(n_motor)) {
    return Malformed("short current command");
  }
  if (HeaderCommand(in[0]) != Command::kCurrent) return Malformed("not a current command");
  for (int i = 0; i < n_motor; ++i) values[i] = GetInt16(&in[1 + 2 * i]);
  return Status::Ok();
}

size_t EncodeCurrentReply(int board_id, const BoardInfo& info, const SensorReply& reply,
                          std::span<uint8_t> out) {
  const size_t n = CurrentReplySize(info.n_motor, info.n_force);
  if (out.size() < n) return 0;
  out[0] = Header(Command::kCurrent, board_id);
  uint8_t* p = &out[1];
  for (int i = 0; i < info.n_motor; ++i, p += 2) PutInt16(p, reply.position[i]);
  for (int i = 0; i < info.n_motor; ++i, p += 2) PutInt16(p, reply.velocity[i]);
  for (int i = 0; i < info.n_force; ++i, p += 2) PutInt16(p, reply.force[i]);
  return n;
}

Status DecodeCurrentReply(std::span<const uint8_t> in, const BoardInfo& info, SensorReply* out) {
  const size_t n = CurrentReplySize(info.n_motor, info.n_force);
  if (in.size() < n) {
    return Malformed("current reply of " + std::to_string(in.size()) + " bytes, expected " +
                     std::to_string(n));
  }
  if (in[0] != Header(Command::kCurrent, info.board_id)) {
    return Malformed("current reply header " + std::to_string(in[0]) + " is not board " +
                     std::to_string(info.board_id) + "'s");
  }
  const uint8_t* p = &in[1];
  for (int i = 0; i < info.n_motor; ++i, p += 2) out->position[i] = GetInt16(p);
  for (int i = 0; i < info.n_motor; ++i, p += 2) out->velocity[i] = GetInt16(p);
  for (int i = 0; i < info.n_force; ++i, p += 2) out->force[i] = GetInt16(p);
  return Status::Ok();
}

}  // namespace rheo::drivers::uart
