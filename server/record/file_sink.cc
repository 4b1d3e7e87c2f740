// FileSink and MemorySink. The file sink writes with write(2) and makes chunks durable with
// fdatasync(2); its errors name the file, and a full disk reports the space left from statvfs(3).
#include <fcntl.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "common/format.h"
#include "record/mcap.h"

namespace rheo::record {

namespace {

ErrorCode CodeForErrno(int err) {
  switch (err) {
    case EACCES:
    case EPERM:
    case EROFS: return ErrorCode::kPermissionDenied;
    case ENOENT:
    case ENOTDIR: return ErrorCode::kNotFound;
    case ENOSPC:
    case EDQUOT:
    case EFBIG: return ErrorCode::kResourceExhausted;
    case EISDIR:
    case ENAMETOOLONG:
    case EINVAL: return ErrorCode::kInvalidArgument;
    default: return ErrorCode::kUnavailable;
  }
}

}  // namespace

Result<std::unique_ptr<FileSink>> FileSink::Create(const std::string& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    return Error{CodeForErrno(err),
                 Format("cannot create the recording %s: %s", path.c_str(), std::strerror(err))};
  }
  return std::unique_ptr<FileSink>(new FileSink(fd, path));
}

FileSink::~FileSink() {
  if (fd_ >= 0) ::close(fd_);
}

Status FileSink::WriteError(int err) const {
  std::string message = Format("writing the recording %s at offset %llu: %s", path_.c_str(),
                               static_cast<unsigned long long>(written_), std::strerror(err));
  if (err == ENOSPC || err == EDQUOT) {
    struct statvfs fs;
    if (::statvfs(path_.c_str(), &fs) == 0) {
      const double free_bytes = static_cast<double>(fs.f_bavail) * static_cast<double>(fs.f_frsize);
      message += Format(" (%.1f MiB free on its file system)", free_bytes / (1024.0 * 1024.0));
    }
  }
  return Error{CodeForErrno(err), std::move(message)};
}

Status FileSink::Write(std::span<const uint8_t> bytes) {
  if (fd_ < 0) return FailedPrecondition(Format("the recording %s is closed", path_.c_str()));
  const uint8_t* p = bytes.data();
  size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return WriteError(errno);
    }
    if (n == 0) return WriteError(ENOSPC);  // write(2) makes no progress only when out of room
    p += n;
    left -= static_cast<size_t>(n);
    written_ += static_cast<uint64_t>(n);
  }
  return Status::Ok();
}

Status FileSink::Flush() {
  if (fd_ < 0) return FailedPrecondition(Format("the recording %s is closed", path_.c_str()));
  if (::fdatasync(fd_) != 0) {
    const int err = errno;
    // A pipe or a character device cannot be synced; there is nothing more to make durable.
    if (err == EINVAL || err == EROFS) return Status::Ok();
    return Error{CodeForErrno(err),
                 Format("syncing the recording %s: %s", path_.c_str(), std::strerror(err))};
  }
  return Status::Ok();
}

Status FileSink::Close() {
  if (fd_ < 0) return Status::Ok();
  Status synced = Flush();
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0 && synced.ok()) {
    const int err = errno;
    return Error{CodeForErrno(err),
                 Format("closing the recording %s: %s", path_.c_str(), std::strerror(err))};
  }
  return synced;
}

Status MemorySink::Write(std::span<const uint8_t> bytes) {
  bytes_.insert(bytes_.end(), bytes.begin(), bytes.end());
  return Status::Ok();
}

}  // namespace rheo::record
