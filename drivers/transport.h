// Byte-level links to a controller. The OS implementations live in rheo_transport
// (termios_transport.h, libusb_transport.h); tests and the emulator stand in for hardware.
#pragma once

#include <cstdint>
#include <memory>
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

/// A serial line that can go away and come back (a USB serial adapter pulled out and plugged in
/// again): how it fares, for status.
struct LineStats {
  bool up = true;               // the link has a line to talk on
  uint64_t losses = 0;          // times the line failed as gone (kUnavailable: EIO, hang-up)
  uint64_t attempts = 0;        // reopens tried (open, raw mode, board identification)
  uint64_t reopens = 0;         // reopens that worked
  int64_t backoff_ns = 0;       // wait before the next attempt while the line is away (0 while up)
  int64_t down_since_ns = 0;    // CLOCK_MONOTONIC when the line went away [ns] (0 while up)
  int64_t last_attempt_ns = 0;  // CLOCK_MONOTONIC when the last reopen was tried [ns] (0: none)
};

/// Where a link gets a new line when the one it uses has gone away. The link calls these on
/// whichever thread holds it (the loop, or a SafeStop under the device's lock); none of them
/// waits, locks or allocates: the reopening itself (open(), tcsetattr, identifying the boards)
/// runs on a thread of the source's own (LineReopener in rheo_transport).
class LineSource {
 public:
  virtual ~LineSource() = default;
  /// The line failed as gone: `line` is handed back to be destroyed off the caller's thread, and
  /// a reopened one is asked for.
  virtual void Lost(std::unique_ptr<ByteTransport> line) = 0;
  /// A reopened line whose boards answered identification, or null while there is none yet.
  virtual std::unique_ptr<ByteTransport> Take() = 0;
  /// Counts since the source was made; `up` is the link's to fill in.
  virtual LineStats stats() const = 0;
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
  /// Whether the link has a line and how its reopening went (links whose line can go away and
  /// be reopened; the others are always up). Same thread as Exchange().
  virtual LineStats line_stats() const { return {}; }
};

}  // namespace rheo::drivers
