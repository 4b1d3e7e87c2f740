// The USB 2.0 "SH4" amplifier board: packet layout and MotorLink. UNVERIFIED: no hardware here
// has confirmed any of it, and no Linux driver has existed. Every assumption about the wire
// format is in this header and sh4_board.cc and nowhere else; see drivers/README.md.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>

#include "drivers/transport.h"
#include "drivers/uart_protocol.h"

namespace rheo::drivers::sh4 {

inline constexpr uint16_t kVendorId = 0x0CEC;   // unverified
inline constexpr uint16_t kProductId = 0x0205;  // unverified
inline constexpr uint8_t kEndpointOut = 0x02;   // bulk OUT, unverified
inline constexpr uint8_t kEndpointIn = 0x86;    // bulk IN, unverified
inline constexpr int kPacketSize = 512;         // one exchange each way per tick
inline constexpr int kChannels = 8;
inline constexpr double kDigitsPerVolt = 415.0;  // DA digits per volt, unverified

/// OUT packet: bytes 0-1 = 0x01 0x0E, bytes 2-17 = 8 DA values int16 LE, rest zero.
void EncodeCommand(std::span<const int16_t> da, std::span<uint8_t, kPacketSize> out);

/// IN packet contents.
struct Sensors {
  std::array<uint16_t, kChannels> counters{};  // bytes 16-31, wrapping, inverted sign
  std::array<uint16_t, kChannels> adc{};       // bytes 32-47
  uint16_t digital = 0;                        // bytes 48-49: bits 4-7 rotary switch
};
Status DecodeSensors(std::span<const uint8_t> in, Sensors* out);

}  // namespace rheo::drivers::sh4

namespace rheo::drivers {

/// MotorLink for one SH4 board (8 channels). Counter offsets live on the host (no reset
/// command); counts are unwrapped by the half-range rule and their sign inverted.
class Sh4MotorLink final : public MotorLink {
 public:
  /// `button_mask`: digital inputs that are grip buttons (bits 0-7; 4-7 are the rotary switch).
  Sh4MotorLink(std::unique_ptr<BulkTransport> transport, uint32_t button_mask,
               int timeout_us = 2000);
  Status Open(int num_motors) override;
  const char* model() const override { return "USB SH4 amplifier board (unverified protocol)"; }
  int max_command() const override { return 32767; }
  Status Exchange(std::span<const int16_t> command, std::span<int64_t> counts,
                  uint32_t* buttons) override;
  /// Rotary switch (board channel), valid after the first exchange.
  int rotary_switch() const { return rotary_; }

 private:
  std::unique_ptr<BulkTransport> transport_;
  uint32_t button_mask_;
  int timeout_us_;
  std::array<uart::CounterUnwrapper, sh4::kChannels> unwrap_;
  int rotary_ = 0;
};

}  // namespace rheo::drivers
