// Byte-level links to a controller. The OS implementations live in rheo_transport
// (termios_transport.h, libusb_transport.h); tests and the emulator stand in for hardware.
#pragma once

#include <cstdint>
#include <span>

#include "common/status.h"

namespace rheo::drivers {

/// A serial byte stream (UART boards). Calls come from one thread at a time.
class ByteTransport {
 public:
  virtual ~ByteTransport() = default;
  /// Writes all of `data` (blocking at most timeout_us) or fails.
  virtual Status Write(std::span<const uint8_t> data, int timeout_us) = 0;
  /// Reads exactly data.size() bytes or fails with kDeadlineExceeded after timeout_us.
  virtual Status ReadExact(std::span<uint8_t> data, int timeout_us) = 0;
  /// Drops whatever has arrived and not been read (resynchronisation).
  virtual void DiscardInput() = 0;
};

/// A USB bulk pipe pair (SH4 board): one OUT transfer, then one IN transfer.
class BulkTransport {
 public:
  virtual ~BulkTransport() = default;
  /// Sends `out` and receives into `in`; returns the number of bytes received.
  virtual Result<size_t> Transfer(std::span<const uint8_t> out, std::span<uint8_t> in,
                                  int timeout_us) = 0;
};

/// One exchange with whatever drives the motors: command digits out, encoder counts in.
class MotorLink {
 public:
  virtual ~MotorLink() = default;
  /// Identifies the controller(s); fails unless exactly `num_motors` motors are present.
  virtual Status Open(int num_motors) = 0;
  /// A short description for DeviceInfo::model, valid after Open().
  virtual const char* model() const = 0;
  /// Largest command magnitude the controller accepts [digits].
  virtual int max_command() const = 0;
  /// Sends one command per motor [digits] and reads the continuous (unwrapped) encoder counts
  /// and the button bits. Must not allocate.
  virtual Status Exchange(std::span<const int16_t> command, std::span<int64_t> counts,
                          uint32_t* buttons) = 0;

  /// Split exchange, for links whose reply takes a while (a serial line): Post() sends the
  /// command and returns without waiting; Collect() reads the reply. Exchange() called while a
  /// reply is outstanding reads and drops that reply first, so the byte stream never goes out of
  /// step whoever calls next. Links that cannot split return false from can_post() and
  /// FailedPrecondition from both. Neither allocates except on error paths.
  virtual bool can_post() const { return false; }
  virtual Status Post(std::span<const int16_t> /*command*/) {
    return FailedPrecondition("this motor link cannot split an exchange");
  }
  virtual Status Collect(std::span<int64_t> /*counts*/, uint32_t* /*buttons*/) {
    return FailedPrecondition("this motor link cannot split an exchange");
  }
  /// A posted command's reply has not been collected (or dropped by Exchange()) yet.
  virtual bool posted() const { return false; }
};

}  // namespace rheo::drivers
