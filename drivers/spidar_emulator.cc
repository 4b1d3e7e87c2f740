#include "drivers/spidar_emulator.h"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <thread>

#include "common/clock.h"
#include "drivers/spidar_kinematics.h"

namespace rheo::drivers {
namespace {

Vec3 RotationVector(const Eigen::Quaterniond& q) {
  Eigen::AngleAxisd aa(q);
  double angle = aa.angle();
  if (angle > M_PI) angle -= 2.0 * M_PI;
  return aa.axis() * angle;
}

}  // namespace

Result<std::unique_ptr<SpidarEmulator>> SpidarEmulator::Start(const SpidarConfig& config,
                                                              const EmulatorOptions& options) {
  if (Status s = ValidateSpidarConfig(config, "emulator config"); !s.ok()) return s.error();
  if (!(options.grip_mass > 0.0) || !(options.physics_step > 0.0) ||
      !(options.lockstep_dt >= options.physics_step)) {
    return InvalidArgument(
        "emulator options: grip_mass and physics_step must be > 0 and lockstep_dt >= "
        "physics_step");
  }
  std::unique_ptr<SpidarEmulator> e(new SpidarEmulator(config, options));
  if (options.line_path.empty()) {
    std::string dir = (std::filesystem::temp_directory_path() / "rheo-spidar-XXXXXX").string();
    if (!mkdtemp(dir.data())) {
      return Error{ErrorCode::kUnavailable,
                   "emulator: cannot make a directory for the line's name under " +
                       std::filesystem::temp_directory_path().string() + ": " +
                       std::strerror(errno)};
    }
    e->own_dir_ = dir;
    e->line_path_ = dir + "/line";
  } else {
    struct stat st {};
    if (lstat(options.line_path.c_str(), &st) == 0 && !S_ISLNK(st.st_mode))
      return InvalidArgument("emulator: line path " + options.line_path +
                             " exists and is not a symbolic link (it is replaced on every replug)");
    e->line_path_ = options.line_path;
  }
  if (Status s = e->OpenLine(); !s.ok()) return s.error();
  e->last_advance_ns_ = MonotonicNowNs();
  e->thread_ = std::thread([p = e.get()] { p->Run(); });
  return e;
}

Status SpidarEmulator::OpenLine() {
  const int master = posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0) {
    const std::string why = std::strerror(errno);
    if (master >= 0) ::close(master);
    return Error{ErrorCode::kUnavailable, "emulator: cannot create a pseudo-terminal: " + why};
  }
  char name[128];
  if (ptsname_r(master, name, sizeof name) != 0) {
    ::close(master);
    return Error{ErrorCode::kUnavailable, "emulator: ptsname failed"};
  }
  const int slave = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (slave < 0) {
    ::close(master);
    return Error{ErrorCode::kUnavailable, std::string("emulator: cannot open ") + name};
  }
  // Raw from the start: no echo or line editing may ever touch the protocol bytes.
  termios tio{};
  tcgetattr(slave, &tio);
  cfmakeraw(&tio);
  tcsetattr(slave, TCSANOW, &tio);
  const int flags = fcntl(master, F_GETFL);
  fcntl(master, F_SETFL, flags | O_NONBLOCK);
  // The stable name moves to the new pty in one step (a new link renamed over the old one), as
  // udev's by-id link does: whoever opens it finds a pty or nothing, never a half-made name.
  const std::string staged = line_path_ + ".new";
  ::unlink(staged.c_str());
  if (::symlink(name, staged.c_str()) != 0 || ::rename(staged.c_str(), line_path_.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    ::unlink(staged.c_str());
    ::close(slave);
    ::close(master);
    return Error{ErrorCode::kUnavailable,
                 "emulator: cannot point " + line_path_ + " at " + name + ": " + why};
  }
  master_fd_ = master;
  slave_fd_ = slave;
  std::lock_guard lock(mutex_);
  if (opened_before_) ++state_.replugs;
  opened_before_ = true;
  pty_path_ = name;
  state_.plugged = true;
  state_.commands_on_line = 0;
  state_.first_command_on_line = {};
  return Status::Ok();
}

void SpidarEmulator::CloseLine() {
  if (master_fd_ < 0) return;
  // The name goes first, as the adapter's by-id link does when it is pulled out.
  ::unlink(line_path_.c_str());
  ::close(slave_fd_);
  ::close(master_fd_);
  slave_fd_ = master_fd_ = -1;
  // A frame cut off by the unplug is gone with the line.
  pending_ = uart::Command::kNone;
  need_ = 0;
  have_ = 0;
  std::lock_guard lock(mutex_);
  pty_path_.clear();
  state_.plugged = false;
}

std::string SpidarEmulator::pty_path() const {
  std::lock_guard lock(mutex_);
  return pty_path_;
}

Status SpidarEmulator::Unplug() {
  return ChangeLine(false);
}

Status SpidarEmulator::Replug() {
  return ChangeLine(true);
}

Status SpidarEmulator::ChangeLine(bool plug) {
  std::lock_guard call(line_call_);
  if (!thread_.joinable()) {  // stopped: nobody else touches the line
    if (!plug) {
      CloseLine();
      return Status::Ok();
    }
    return master_fd_ >= 0 ? Status::Ok() : OpenLine();
  }
  line_want_.store(plug ? 1 : 0, std::memory_order_relaxed);
  const uint64_t request = line_request_.fetch_add(1, std::memory_order_acq_rel) + 1;
  // The thread looks at least every 5 ms (lockstep) or 1 ms.
  for (int i = 0; i < 5000 && line_done_.load(std::memory_order_acquire) < request; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  if (line_done_.load(std::memory_order_acquire) < request)
    return Error{ErrorCode::kDeadlineExceeded, "emulator: the line did not change within 5 s"};
  std::lock_guard lock(mutex_);
  return line_result_;
}

SpidarEmulator::SpidarEmulator(const SpidarConfig& config, const EmulatorOptions& options)
    : config_(config), options_(options) {
  info_.board_id = options.board_id;
  info_.model = options.model;
  info_.n_target = 0;
  info_.n_motor = kSpidarStrings;
  info_.n_current = kSpidarStrings;
  info_.n_force = 4;
  info_.n_touch = 0;
  inertia_ = options.grip_inertia > 0.0
                 ? options.grip_inertia
                 : 0.4 * options.grip_mass * config.grip_radius * config.grip_radius;
  state_.pose = options.initial_pose;
  state_.holding = options.hand_holds_at_start;
  hand_target_ = options.initial_pose;
  StringGeometry g;
  ComputeStringGeometry(config_, state_.pose, &g);
  power_on_length_ = g.length;
  last_length_ = g.length;
  state_.lengths = g.length;
}

SpidarEmulator::~SpidarEmulator() {
  Stop();
  CloseLine();
  if (!own_dir_.empty()) ::rmdir(own_dir_.c_str());
}

void SpidarEmulator::Stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void SpidarEmulator::HoldHand(const Pose& target) {
  std::lock_guard lock(mutex_);
  hand_script_ = nullptr;
  hand_target_ = target;
  state_.holding = true;
}

void SpidarEmulator::ScriptHand(std::function<Pose(double)> script) {
  std::lock_guard lock(mutex_);
  hand_script_ = std::move(script);
  state_.holding = true;
}

void SpidarEmulator::ReleaseHand() {
  std::lock_guard lock(mutex_);
  hand_script_ = nullptr;
  state_.holding = false;
}

void SpidarEmulator::SetHandWrench(const Wrench& wrench) {
  std::lock_guard lock(mutex_);
  hand_wrench_ = wrench;
}

GripSnapshot SpidarEmulator::Snapshot() const {
  std::lock_guard lock(mutex_);
  return state_;
}

void SpidarEmulator::Run() {
  if (options_.realtime_priority > 0) {
    sched_param param{};
    param.sched_priority = options_.realtime_priority;
    realtime_ = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  }
  std::array<uint8_t, 256> buf;
  while (!stop_.load(std::memory_order_acquire)) {
    if (const uint64_t request = line_request_.load(std::memory_order_acquire);
        request != line_done_.load(std::memory_order_relaxed)) {
      Status done = Status::Ok();
      if (line_want_.load(std::memory_order_relaxed) == 0) {
        CloseLine();
      } else if (master_fd_ < 0) {
        done = OpenLine();
      }
      {
        std::lock_guard lock(mutex_);
        line_result_ = done;
      }
      line_done_.store(request, std::memory_order_release);
    }
    pollfd p{master_fd_, POLLIN, 0};
    // Real time: wake at least every 0.5 ms so the grip keeps moving between commands. Unplugged,
    // the grip moves on the same way (the board keeps its last command).
    int r = 0;
    if (master_fd_ >= 0) {
      r = poll(&p, 1, options_.lockstep ? 5 : 1);
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(options_.lockstep ? 5 : 1));
    }
    if (!options_.lockstep) {
      const int64_t now = MonotonicNowNs();
      std::lock_guard lock(mutex_);
      // After a long pause (debugger, overload) do not replay more than 50 ms of physics.
      Advance(std::min((now - last_advance_ns_) * 1e-9, 0.05));
      last_advance_ns_ = now;
    }
    if (r <= 0 || !(p.revents & POLLIN)) continue;
    const ssize_t n = ::read(master_fd_, buf.data(), buf.size());
    for (ssize_t i = 0; i < n; ++i) OnByte(buf[i]);
  }
}

void SpidarEmulator::OnByte(uint8_t byte) {
  if (need_ > 0) {
    frame_[have_++] = byte;
    if (--need_ == 0 && pending_ == uart::Command::kCurrent) {
      if (pending_board_ == info_.board_id) ApplyCurrentCommand();
      pending_ = uart::Command::kNone;
    }
    return;
  }
  if (byte == 0) return;  // padding, resynchronisation, or "none" to board 0
  const uart::Command cmd = uart::HeaderCommand(byte);
  const int board = uart::HeaderBoard(byte);
  switch (cmd) {
    case uart::Command::kNone: return;
    case uart::Command::kBoardInfo:
      if (board == info_.board_id) {
        std::array<uint8_t, uart::kBoardInfoReplySize> reply;
        uart::EncodeBoardInfoReply(info_, reply);
        SendReply(reply);
        std::lock_guard lock(mutex_);
        ++state_.enumerations;
      }
      return;
    case uart::Command::kCurrent:
      pending_ = cmd;
      pending_board_ = board;
      frame_[0] = byte;
      have_ = 1;
      need_ = 2 * static_cast<size_t>(info_.n_motor);
      return;
    case uart::Command::kResetSensor:
      if (board == info_.board_id) {
        std::lock_guard lock(mutex_);
        power_on_length_ = state_.lengths;
      }
      return;
    default: {
      std::lock_guard lock(mutex_);
      ++state_.protocol_errors;
      return;
    }
  }
}

void SpidarEmulator::ApplyCurrentCommand() {
  std::array<int16_t, kSpidarStrings> values{};
  uart::DecodeCurrentCommand(std::span(frame_.data(), have_), info_.n_motor, values);
  uart::SensorReply reply;
  {
    std::lock_guard lock(mutex_);
    for (int i = 0; i < kSpidarStrings; ++i) {
      const SpidarString& s = config_.strings[i];
      const double t =
          s.command_sign * values[i] / (config_.board.digits_per_volt * s.volts_per_newton);
      state_.tensions[i] = std::max(t, 0.0);  // a string pulls; it cannot push
    }
    state_.last_command = values;
    state_.last_command_ns = MonotonicNowNs();
    ++state_.current_commands;
    if (state_.commands_on_line++ == 0) state_.first_command_on_line = values;
    if (options_.lockstep) Advance(options_.lockstep_dt);
    Encoders(&reply);
  }
  std::array<uint8_t, uart::kMaxFrameSize> out;
  const size_t n = uart::EncodeCurrentReply(info_.board_id, info_, reply, out);
  SendReply(std::span(out.data(), n));
}

void SpidarEmulator::Encoders(uart::SensorReply* reply) const {
  for (int i = 0; i < kSpidarStrings; ++i) {
    const double mpc = config_.strings[i].metres_per_count;
    const auto count =
        static_cast<int64_t>(std::floor((state_.lengths[i] - power_on_length_[i]) / mpc));
    reply->position[i] = static_cast<int16_t>(static_cast<uint16_t>(count & 0xFFFF));
    // Velocity in counts per millisecond over the last advance, saturating.
    const double ms = std::max(last_advance_s_ * 1e3, 1e-3);
    const double rate = (state_.lengths[i] - last_length_[i]) / mpc / ms;
    reply->velocity[i] = static_cast<int16_t>(std::clamp(rate, -32767.0, 32767.0));
  }
}

void SpidarEmulator::Advance(double seconds) {
  last_length_ = state_.lengths;
  last_advance_s_ = seconds;
  const double h = options_.physics_step;
  double left = seconds;
  while (left > 0.5 * h) {
    Step(h);
    left -= h;
  }
}

void SpidarEmulator::Step(double h) {
  GripSnapshot& s = state_;
  const Eigen::Matrix3d r = s.pose.orientation.toRotationMatrix();
  Vec3 f = Vec3::Zero(), tau = Vec3::Zero();
  for (int i = 0; i < kSpidarStrings; ++i) {
    const SpidarString& str = config_.strings[i];
    const Vec3 rg = r * str.grip_point;
    const Vec3 w = str.motor_exit - (s.pose.position + rg);
    const double len = w.norm();
    s.lengths[i] = len;
    if (len <= 0.0) continue;
    const Vec3 pull = s.tensions[i] * w / len;
    f += pull;
    tau += rg.cross(pull);
  }
  s.strings.force = f;
  s.strings.torque = tau;

  Vec3 fh = hand_wrench_.force, th = hand_wrench_.torque;
  if (s.holding) {
    if (hand_script_) hand_target_ = hand_script_(s.time);
    fh += options_.hand_stiffness * (hand_target_.position - s.pose.position) -
          options_.hand_damping * s.velocity;
    th += options_.hand_angular_stiffness *
              RotationVector(hand_target_.orientation * s.pose.orientation.conjugate()) -
          options_.hand_angular_damping * s.angular_velocity;
  }
  s.hand.force = fh;
  s.hand.torque = th;

  const Vec3 force =
      f + fh + options_.grip_mass * options_.gravity - options_.linear_damping * s.velocity;
  const Vec3 torque = tau + th - options_.angular_damping * s.angular_velocity;
  // Semi-implicit Euler: velocities first, then positions with the new velocities.
  s.velocity += h * force / options_.grip_mass;
  s.angular_velocity += h * torque / inertia_;
  s.pose.position += h * s.velocity;
  const Vec3 dr = h * s.angular_velocity;
  if (dr.norm() > 0.0) {
    s.pose.orientation =
        Eigen::Quaterniond(Eigen::AngleAxisd(dr.norm(), dr.normalized())) * s.pose.orientation;
    s.pose.orientation.normalize();
  }
  s.time += h;
  StringGeometry g;
  ComputeStringGeometry(config_, s.pose, &g);
  s.lengths = g.length;
}

void SpidarEmulator::SetLineFault(LineFault fault, int delay_us) {
  line_delay_us_.store(std::max(0, delay_us), std::memory_order_relaxed);
  line_fault_.store(fault, std::memory_order_release);
}

void SpidarEmulator::SendReply(std::span<const uint8_t> reply) {
  std::span<const uint8_t> bytes = reply;
  std::array<uint8_t, uart::kMaxFrameSize> damaged;
  switch (line_fault_.load(std::memory_order_acquire)) {
    case LineFault::kSilent: return;
    case LineFault::kCorrupt: {
      // Every byte inverted: the header no longer names the board, and checksums fail.
      const size_t n = std::min(reply.size(), damaged.size());
      for (size_t i = 0; i < n; ++i) damaged[i] = static_cast<uint8_t>(~reply[i]);
      bytes = std::span<const uint8_t>(damaged.data(), n);
      break;
    }
    case LineFault::kDelayed:
      std::this_thread::sleep_for(
          std::chrono::microseconds(line_delay_us_.load(std::memory_order_relaxed)));
      break;
    case LineFault::kNone: break;
  }
  size_t done = 0;
  int spins = 0;
  while (done < bytes.size() && spins < 1000) {
    const ssize_t n = ::write(master_fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
    } else if (n < 0 && errno != EAGAIN && errno != EINTR) {
      return;
    } else {
      pollfd p{master_fd_, POLLOUT, 0};
      poll(&p, 1, 1);
      ++spins;
    }
  }
}

}  // namespace rheo::drivers
