// CRC32 through zlib, chunk compression through libzstd and liblz4's frame API (the LZ4 frame
// format is what MCAP's "lz4" means; a raw LZ4 block would not be read by other tools).
#include "record/mcap_format.h"

#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include "common/format.h"

namespace rheo::record {

std::string_view CompressionName(Compression c) {
  switch (c) {
    case Compression::kNone: return "";
    case Compression::kZstd: return "zstd";
    case Compression::kLz4: return "lz4";
  }
  return "";
}

namespace internal {

std::string OpcodeName(uint8_t op) {
  switch (op) {
    case kOpHeader: return "Header";
    case kOpFooter: return "Footer";
    case kOpSchema: return "Schema";
    case kOpChannel: return "Channel";
    case kOpMessage: return "Message";
    case kOpChunk: return "Chunk";
    case kOpMessageIndex: return "Message Index";
    case kOpChunkIndex: return "Chunk Index";
    case kOpAttachment: return "Attachment";
    case kOpAttachmentIndex: return "Attachment Index";
    case kOpStatistics: return "Statistics";
    case kOpMetadata: return "Metadata";
    case kOpMetadataIndex: return "Metadata Index";
    case kOpSummaryOffset: return "Summary Offset";
    case kOpDataEnd: return "Data End";
  }
  return Format("opcode 0x%02x", op);
}

uint32_t Crc32(uint32_t crc, std::span<const uint8_t> bytes) {
  return static_cast<uint32_t>(crc32_z(crc, bytes.data(), bytes.size()));
}

namespace {

class ZstdCompressor final : public Compressor {
 public:
  explicit ZstdCompressor(ZSTD_CCtx* cctx) : cctx_(cctx) {}
  ~ZstdCompressor() override { ZSTD_freeCCtx(cctx_); }

  Result<std::span<const uint8_t>> Compress(std::span<const uint8_t> in) override {
    const size_t bound = ZSTD_compressBound(in.size());
    if (out_.size() < bound) out_.resize(bound);
    const size_t n = ZSTD_compress2(cctx_, out_.data(), out_.size(), in.data(), in.size());
    if (ZSTD_isError(n)) {
      return Internal(Format("zstd compression of a %zu-byte chunk failed: %s", in.size(),
                             ZSTD_getErrorName(n)));
    }
    return std::span<const uint8_t>(out_.data(), n);
  }

 private:
  ZSTD_CCtx* cctx_;
  std::vector<uint8_t> out_;
};

class Lz4Compressor final : public Compressor {
 public:
  explicit Lz4Compressor(LZ4F_cctx* cctx) : cctx_(cctx) {}
  ~Lz4Compressor() override { LZ4F_freeCompressionContext(cctx_); }

  Result<std::span<const uint8_t>> Compress(std::span<const uint8_t> in) override {
    LZ4F_preferences_t prefs;
    std::memset(&prefs, 0, sizeof prefs);
    prefs.frameInfo.contentSize = in.size();  // lets a reader check the size before decoding
    prefs.autoFlush = 1;                      // no staging copy inside the context
    const size_t bound = LZ4F_HEADER_SIZE_MAX + LZ4F_compressBound(in.size(), &prefs) +
                         LZ4F_compressBound(0, &prefs);
    if (out_.size() < bound) out_.resize(bound);
    uint8_t* dst = out_.data();
    size_t cap = out_.size();
    size_t pos = LZ4F_compressBegin(cctx_, dst, cap, &prefs);
    if (!LZ4F_isError(pos)) {
      const size_t n =
          LZ4F_compressUpdate(cctx_, dst + pos, cap - pos, in.data(), in.size(), nullptr);
      pos = LZ4F_isError(n) ? n : pos + n;
    }
    if (!LZ4F_isError(pos)) {
      const size_t n = LZ4F_compressEnd(cctx_, dst + pos, cap - pos, nullptr);
      pos = LZ4F_isError(n) ? n : pos + n;
    }
    if (LZ4F_isError(pos)) {
      return Internal(Format("lz4 compression of a %zu-byte chunk failed: %s", in.size(),
                             LZ4F_getErrorName(pos)));
    }
    return std::span<const uint8_t>(out_.data(), pos);
  }

 private:
  LZ4F_cctx* cctx_;
  std::vector<uint8_t> out_;
};

}  // namespace

Result<std::unique_ptr<Compressor>> MakeCompressor(Compression compression, int zstd_level) {
  switch (compression) {
    case Compression::kNone: return std::unique_ptr<Compressor>();
    case Compression::kZstd: {
      if (zstd_level < 1 || zstd_level > ZSTD_maxCLevel()) {
        return InvalidArgument(
            Format("zstd_level %d is outside 1 .. %d", zstd_level, ZSTD_maxCLevel()));
      }
      ZSTD_CCtx* cctx = ZSTD_createCCtx();
      if (cctx == nullptr) return Internal("ZSTD_createCCtx failed (out of memory)");
      const size_t r = ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, zstd_level);
      if (ZSTD_isError(r)) {
        ZSTD_freeCCtx(cctx);
        return Internal(Format("zstd level %d refused: %s", zstd_level, ZSTD_getErrorName(r)));
      }
      return std::unique_ptr<Compressor>(new ZstdCompressor(cctx));
    }
    case Compression::kLz4: {
      LZ4F_cctx* cctx = nullptr;
      const size_t r = LZ4F_createCompressionContext(&cctx, LZ4F_VERSION);
      if (LZ4F_isError(r)) {
        return Internal(Format("LZ4F_createCompressionContext failed: %s", LZ4F_getErrorName(r)));
      }
      return std::unique_ptr<Compressor>(new Lz4Compressor(cctx));
    }
  }
  return InvalidArgument("unknown compression");
}

struct Decompressor::Contexts {
  ZSTD_DCtx* zstd = nullptr;
  LZ4F_dctx* lz4 = nullptr;
  ~Contexts() {
    if (zstd != nullptr) ZSTD_freeDCtx(zstd);
    if (lz4 != nullptr) LZ4F_freeDecompressionContext(lz4);
  }
};

Decompressor::Decompressor() : c_(std::make_unique<Contexts>()) {}
Decompressor::~Decompressor() = default;

Status Decompressor::Decompress(Compression compression, std::span<const uint8_t> in, uint64_t size,
                                std::vector<uint8_t>& out) {
  out.resize(static_cast<size_t>(size));
  // LZ4F and zstd want a non-null destination even for an empty chunk.
  uint8_t dummy = 0;
  uint8_t* dst = out.empty() ? &dummy : out.data();
  switch (compression) {
    case Compression::kNone:
      if (in.size() != size) {
        return DataLoss(Format("uncompressed records are %zu bytes, the header says %llu",
                               in.size(), static_cast<unsigned long long>(size)));
      }
      if (size > 0) std::memcpy(dst, in.data(), in.size());
      return Status::Ok();
    case Compression::kZstd: {
      if (c_->zstd == nullptr) c_->zstd = ZSTD_createDCtx();
      if (c_->zstd == nullptr) return Internal("ZSTD_createDCtx failed (out of memory)");
      const size_t n = ZSTD_decompressDCtx(c_->zstd, dst, out.size(), in.data(), in.size());
      if (ZSTD_isError(n)) {
        return DataLoss(Format("zstd: %s", ZSTD_getErrorName(n)));
      }
      if (n != size) {
        return DataLoss(Format("zstd yielded %zu bytes, the header says %llu", n,
                               static_cast<unsigned long long>(size)));
      }
      return Status::Ok();
    }
    case Compression::kLz4: {
      if (c_->lz4 == nullptr) {
        const size_t r = LZ4F_createDecompressionContext(&c_->lz4, LZ4F_VERSION);
        if (LZ4F_isError(r)) {
          c_->lz4 = nullptr;
          return Internal(Format("LZ4F_createDecompressionContext: %s", LZ4F_getErrorName(r)));
        }
      }
      LZ4F_resetDecompressionContext(c_->lz4);
      size_t src_pos = 0;
      size_t dst_pos = 0;
      for (;;) {
        size_t dst_n = out.size() - dst_pos;
        size_t src_n = in.size() - src_pos;
        const size_t hint =
            LZ4F_decompress(c_->lz4, dst + dst_pos, &dst_n, in.data() + src_pos, &src_n, nullptr);
        if (LZ4F_isError(hint)) return DataLoss(Format("lz4: %s", LZ4F_getErrorName(hint)));
        src_pos += src_n;
        dst_pos += dst_n;
        if (hint == 0) break;  // end of the frame
        if (src_n == 0 && dst_n == 0) {
          return DataLoss(src_pos == in.size()
                              ? Format("lz4: the frame ends early (%zu of %llu bytes decoded)",
                                       dst_pos, static_cast<unsigned long long>(size))
                              : Format("lz4: the frame holds more than the header's %llu bytes",
                                       static_cast<unsigned long long>(size)));
        }
      }
      if (dst_pos != size) {
        return DataLoss(Format("lz4 yielded %zu bytes, the header says %llu", dst_pos,
                               static_cast<unsigned long long>(size)));
      }
      if (src_pos != in.size()) {
        return DataLoss(Format("lz4: %zu bytes follow the end of the frame", in.size() - src_pos));
      }
      return Status::Ok();
    }
  }
  return InvalidArgument("unknown compression");
}

}  // namespace internal
}  // namespace rheo::record
