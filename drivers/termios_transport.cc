#include "drivers/termios_transport.h"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

#include "common/clock.h"

namespace rheo::drivers {
namespace {

speed_t BaudConstant(int baud) {
  switch (baud) {
    case 9600: return B9600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    default: return B0;
  }
}

enum class Wait { kReady, kTimeout, kHungUp };

// Waits for `events` on fd until `deadline_ns`. kHungUp: the other end of the line is gone (a
// USB serial adapter pulled out, a pty whose master closed); nothing will ever arrive.
Wait WaitFor(int fd, short events, int64_t deadline_ns) {
  for (;;) {
    const int64_t left_ns = deadline_ns - MonotonicNowNs();
    if (left_ns <= 0) return Wait::kTimeout;
    pollfd p{fd, events, 0};
    // poll() takes milliseconds; ppoll() takes the finer deadline.
    timespec ts{static_cast<time_t>(left_ns / 1'000'000'000),
                static_cast<long>(left_ns % 1'000'000'000)};
    const int r = ppoll(&p, 1, &ts, nullptr);
    if (r > 0) {
      // A hung-up tty also polls readable (its reads return 0 for ever). The callers wait only
      // after a read or write that moved nothing, so no data is left behind here.
      if (p.revents & (POLLHUP | POLLERR | POLLNVAL)) return Wait::kHungUp;
      if (p.revents & events) return Wait::kReady;
    }
    if (r < 0 && errno != EINTR) return Wait::kHungUp;
  }
}

}  // namespace

Result<std::unique_ptr<TermiosTransport>> TermiosTransport::Open(const std::string& path,
                                                                 int baud) {
  const speed_t speed = BaudConstant(baud);
  if (speed == B0) {
    return InvalidArgument("serial port " + path + ": unsupported baud rate " +
                           std::to_string(baud));
  }
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    return Error{ErrorCode::kUnavailable,
                 "serial port " + path + ": cannot open: " + std::strerror(errno) +
                     (errno == EACCES ? " (is the user in the dialout group?)" : "")};
  }
  termios tio{};
  if (tcgetattr(fd, &tio) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return Error{ErrorCode::kUnavailable, "serial port " + path + ": not a terminal: " + why};
  }
  cfmakeraw(&tio);
  tio.c_cflag &= ~(CSTOPB | PARENB | CRTSCTS | CSIZE);
  tio.c_cflag |= CS8 | CLOCAL | CREAD;
  tio.c_iflag &= ~(IXON | IXOFF | IXANY);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  cfsetispeed(&tio, speed);
  cfsetospeed(&tio, speed);
  if (tcsetattr(fd, TCSANOW, &tio) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return Error{ErrorCode::kUnavailable, "serial port " + path + ": cannot set 8N1 raw mode at " +
                                              std::to_string(baud) + " bit/s: " + why};
  }
  tcflush(fd, TCIOFLUSH);
  return std::unique_ptr<TermiosTransport>(new TermiosTransport(fd, path));
}

TermiosTransport::~TermiosTransport() {
  ::close(fd_);
}

Status TermiosTransport::Write(std::span<const uint8_t> data, int timeout_us) {
  const int64_t deadline = MonotonicNowNs() + int64_t{timeout_us} * 1000;
  size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd_, data.data() + done, data.size() - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      return Error{ErrorCode::kUnavailable,
                   "serial port " + path_ + ": write failed: " + std::strerror(errno)};
    }
    const Wait w = WaitFor(fd_, POLLOUT, deadline);
    if (w == Wait::kHungUp)
      return Error{ErrorCode::kUnavailable, "serial port " + path_ + ": hung up"};
    if (w == Wait::kTimeout) {
      return Error{ErrorCode::kDeadlineExceeded, "serial port " + path_ + ": write timed out"};
    }
  }
  return Status::Ok();
}

Status TermiosTransport::ReadExact(std::span<uint8_t> data, int timeout_us) {
  const int64_t deadline = MonotonicNowNs() + int64_t{timeout_us} * 1000;
  size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::read(fd_, data.data() + done, data.size() - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      return Error{ErrorCode::kUnavailable,
                   "serial port " + path_ + ": read failed: " + std::strerror(errno)};
    }
    const Wait w = WaitFor(fd_, POLLIN, deadline);
    if (w == Wait::kHungUp)
      return Error{ErrorCode::kUnavailable, "serial port " + path_ + ": hung up"};
    if (w == Wait::kTimeout) {
      return Error{ErrorCode::kDeadlineExceeded,
                   "serial port " + path_ + ": " + std::to_string(done) + " of " +
                       std::to_string(data.size()) + " bytes within " + std::to_string(timeout_us) +
                       " us"};
    }
  }
  return Status::Ok();
}

void TermiosTransport::DiscardInput() {
  tcflush(fd_, TCIFLUSH);
}

}  // namespace rheo::drivers
