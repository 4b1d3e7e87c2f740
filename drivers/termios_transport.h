// ByteTransport over a serial port or pseudo-terminal: termios raw mode, 8N1, no flow control.
#pragma once

#include <memory>
#include <string>

#include "drivers/transport.h"

namespace rheo::drivers {

class TermiosTransport final : public ByteTransport {
 public:
  static constexpr int kDefaultBaud = 2'000'000;  // the UART motor boards [bit/s]

  /// Opens `path` (e.g. /dev/ttyUSB0 or an emulator's pty) in raw 8N1 mode at `baud`.
  static Result<std::unique_ptr<TermiosTransport>> Open(const std::string& path,
                                                        int baud = kDefaultBaud);
  ~TermiosTransport() override;

  Status Write(std::span<const uint8_t> data, int timeout_us) override;
  Status ReadExact(std::span<uint8_t> data, int timeout_us) override;
  void DiscardInput() override;

 private:
  TermiosTransport(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  int fd_;
  std::string path_;
};

}  // namespace rheo::drivers
