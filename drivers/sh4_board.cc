// UNVERIFIED protocol (see sh4_board.h): reconstructed from old public host code, never run
// against a board here.
#include "drivers/sh4_board.h"

#include <cstring>
#include <string>

namespace rheo::drivers {
namespace sh4 {

void EncodeCommand(std::span<const int16_t> da, std::span<uint8_t, kPacketSize> out) {
  std::memset(out.data(), 0, kPacketSize);
  out[0] = 0x01;
  out[1] = 0x0E;
  for (int i = 0; i < kChannels && i < static_cast<int>(da.size()); ++i) {
    const auto u = static_cast<uint16_t>(da[i]);
    out[2 + 2 * i] = static_cast<uint8_t>(u & 0xFF);
    out[3 + 2 * i] = static_cast<uint8_t>(u >> 8);
  }
}

Status DecodeSensors(std::span<const uint8_t> in, Sensors* out) {
  if (in.size() < 50) {
    return Error{ErrorCode::kUnavailable,
                 "SH4 board: IN packet of " + std::to_string(in.size()) + " bytes, need 50"};
  }
  auto u16 = [&](int at) { return static_cast<uint16_t>(in[at] | (in[at + 1] << 8)); };
  for (int i = 0; i < kChannels; ++i) {
    out->counters[i] = u16(16 + 2 * i);
    out->adc[i] = u16(32 + 2 * i);
  }
  out->digital = u16(48);
  return Status::Ok();
}

}  // namespace sh4

Sh4MotorLink::Sh4MotorLink(std::unique_ptr<BulkTransport> transport, uint32_t button_mask,
                           int timeout_us)
    : transport_(std::move(transport)), button_mask_(button_mask), timeout_us_(timeout_us) {}

Status Sh4MotorLink::Open(int num_motors) {
  if (num_motors != sh4::kChannels) {
    return Error{ErrorCode::kFailedPrecondition,
                 "SH4 board drives 8 motors, the device has " + std::to_string(num_motors)};
  }
  for (auto& u : unwrap_) u.Reset();
  // No identification command is known: one zero-output exchange proves the pipe works.
  std::array<int16_t, sh4::kChannels> zero{};
  std::array<int64_t, sh4::kChannels> counts{};
  uint32_t buttons = 0;
  return Exchange(zero, counts, &buttons);
}

Status Sh4MotorLink::Exchange(std::span<const int16_t> command, std::span<int64_t> counts,
                              uint32_t* buttons) {
  std::array<uint8_t, sh4::kPacketSize> out, in;
  sh4::EncodeCommand(command, std::span<uint8_t, sh4::kPacketSize>(out));
  auto got = transport_->Transfer(out, in, timeout_us_);
  if (!got.ok()) return got.error();
  sh4::Sensors s;
  if (Status st = sh4::DecodeSensors(std::span(in.data(), *got), &s); !st.ok()) return st;
  for (int i = 0; i < sh4::kChannels; ++i) {
    // Counters count down as the string lengthens: invert after unwrapping.
    counts[i] = -unwrap_[i].Update(s.counters[i]);
  }
  rotary_ = (s.digital >> 4) & 0xF;
  *buttons = s.digital & button_mask_;
  return Status::Ok();
}

}  // namespace rheo::drivers
