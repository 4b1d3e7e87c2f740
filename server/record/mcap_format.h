// The MCAP wire format shared by the writer and the reader: opcodes, the magic, little-endian
// field encoding, CRC32 and the chunk compressors. Internal to rheo_record.
#pragma once

#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "record/mcap.h"

namespace rheo::record::internal {

/// Record opcodes (spec: "Records").
enum Opcode : uint8_t {
  kOpHeader = 0x01,
  kOpFooter = 0x02,
  kOpSchema = 0x03,
  kOpChannel = 0x04,
  kOpMessage = 0x05,
  kOpChunk = 0x06,
  kOpMessageIndex = 0x07,
  kOpChunkIndex = 0x08,
  kOpAttachment = 0x09,
  kOpAttachmentIndex = 0x0A,
  kOpStatistics = 0x0B,
  kOpMetadata = 0x0C,
  kOpMetadataIndex = 0x0D,
  kOpSummaryOffset = 0x0E,
  kOpDataEnd = 0x0F,
};

/// "Header", "Chunk", ... for messages; "opcode 0x9a" for an unknown one.
std::string OpcodeName(uint8_t op);

/// 0x89 'M' 'C' 'A' 'P' '0' '\r' '\n': the first and last 8 bytes of every file.
inline constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
inline constexpr size_t kRecordPrefix = 9;    // opcode (1) + content length (8) [bytes]
inline constexpr size_t kFooterContent = 20;  // summary_start, summary_offset_start, summary_crc
inline constexpr size_t kMessageFixed = 22;   // channel_id 2, sequence 4, log_time 8, publish 8
inline constexpr size_t kFooterRecord = kRecordPrefix + kFooterContent;

/// CRC-32 (IEEE 802.3, zlib's crc32) of `bytes`, continuing from `crc` (0 to start).
uint32_t Crc32(uint32_t crc, std::span<const uint8_t> bytes);

// Little-endian fields appended to a byte buffer whose capacity the caller reuses.
inline void PutU8(std::vector<uint8_t>& b, uint8_t v) {
  b.push_back(v);
}
inline void PutU16(std::vector<uint8_t>& b, uint16_t v) {
  const uint8_t le[2] = {uint8_t(v), uint8_t(v >> 8)};
  b.insert(b.end(), le, le + 2);
}
inline void PutU32(std::vector<uint8_t>& b, uint32_t v) {
  const uint8_t le[4] = {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)};
  b.insert(b.end(), le, le + 4);
}
inline void PutU64(std::vector<uint8_t>& b, uint64_t v) {
  uint8_t le[8];
  for (int i = 0; i < 8; ++i) le[i] = uint8_t(v >> (8 * i));
  b.insert(b.end(), le, le + 8);
}
inline void PutBytes(std::vector<uint8_t>& b, std::span<const uint8_t> bytes) {
  b.insert(b.end(), bytes.begin(), bytes.end());
}
/// String: uint32 byte length, then the bytes.
inline void PutString(std::vector<uint8_t>& b, std::string_view s) {
  PutU32(b, static_cast<uint32_t>(s.size()));
  b.insert(b.end(), s.begin(), s.end());
}
/// Overwrites 8 bytes at `at` (a record's content length, known once the content is appended).
inline void PatchU64(std::vector<uint8_t>& b, size_t at, uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + i] = uint8_t(v >> (8 * i));
}

inline uint16_t LoadU16(const uint8_t* p) {
  return uint16_t(p[0] | (p[1] << 8));
}
inline uint32_t LoadU32(const uint8_t* p) {
  return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}
inline uint64_t LoadU64(const uint8_t* p) {
  return uint64_t(LoadU32(p)) | (uint64_t(LoadU32(p + 4)) << 32);
}

/// Bounds-checked little-endian reads over one record's content. A read past the end returns
/// zero or empty and clears ok(), so a parser reads every field and checks ok() once.
class FieldReader {
 public:
  explicit FieldReader(std::span<const uint8_t> bytes) : p_(bytes.data()), n_(bytes.size()) {}

  bool ok() const { return ok_; }
  size_t remaining() const { return n_ - pos_; }

  uint8_t U8() { return Take(1) ? p_[pos_ - 1] : 0; }
  uint16_t U16() { return Take(2) ? LoadU16(p_ + pos_ - 2) : 0; }
  uint32_t U32() { return Take(4) ? LoadU32(p_ + pos_ - 4) : 0; }
  uint64_t U64() { return Take(8) ? LoadU64(p_ + pos_ - 8) : 0; }
  std::span<const uint8_t> Bytes(uint64_t n) {
    if (!Take(n)) return {};
    return {p_ + pos_ - n, static_cast<size_t>(n)};
  }
  std::string_view String() {
    auto b = Bytes(U32());
    return {reinterpret_cast<const char*>(b.data()), b.size()};
  }
  /// The rest of the content (e.g. a Message's data).
  std::span<const uint8_t> Rest() { return Bytes(remaining()); }

 private:
  bool Take(uint64_t n) {
    if (!ok_ || n > n_ - pos_) {
      ok_ = false;
      return false;
    }
    pos_ += static_cast<size_t>(n);
    return true;
  }

  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
  bool ok_ = true;
};

/// Compresses whole chunks with one reused context and output buffer.
class Compressor {
 public:
  virtual ~Compressor() = default;
  /// The compressed form of `in`, valid until the next call.
  virtual Result<std::span<const uint8_t>> Compress(std::span<const uint8_t> in) = 0;
};

/// A compressor for kZstd (at `zstd_level`) or kLz4; null for kNone.
Result<std::unique_ptr<Compressor>> MakeCompressor(Compression compression, int zstd_level);

/// Decompresses chunks; holds a zstd and an LZ4 context, made on first use.
class Decompressor {
 public:
  Decompressor();
  ~Decompressor();
  Decompressor(const Decompressor&) = delete;
  Decompressor& operator=(const Decompressor&) = delete;

  /// Decompresses `in` into `out`, resized to `size`; fails unless it yields exactly `size` bytes
  /// and consumes all of `in`. The error says what the library reported.
  Status Decompress(Compression compression, std::span<const uint8_t> in, uint64_t size,
                    std::vector<uint8_t>& out);

 private:
  struct Contexts;
  std::unique_ptr<Contexts> c_;
};

}  // namespace rheo::record::internal
