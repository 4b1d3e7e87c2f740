// McapReader: one forward scan of the data section's record headers (chunks are not decompressed
// to open a file), the summary through the footer, and a cursor that merges the chunks' messages
// by log time with a heap, keeping only the chunks whose time ranges overlap decompressed.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "common/format.h"
#include "record/mcap.h"
#include "record/mcap_format.h"

namespace rheo::record {

using namespace internal;  // NOLINT: the wire-format helpers of this library

namespace {

using ull = unsigned long long;

/// The bytes of the file, owned in one of three ways.
struct Storage {
  virtual ~Storage() = default;
  std::span<const uint8_t> bytes;
};
struct VectorStorage final : Storage {
  explicit VectorStorage(std::vector<uint8_t> v) : data(std::move(v)) { bytes = data; }
  std::vector<uint8_t> data;
};
struct MappedStorage final : Storage {
  MappedStorage(void* a, size_t n) : addr(a), size(n) {
    bytes = {static_cast<const uint8_t*>(a), n};
  }
  ~MappedStorage() override { ::munmap(addr, size); }
  void* addr;
  size_t size;
};

/// A run of records to parse for messages: a Chunk's records, or consecutive records outside
/// chunks that include at least one Message.
struct Segment {
  uint64_t offset = 0;  // of the Chunk record, or of the run's first record [bytes]
  uint64_t start_time = 0, end_time = 0;  // log-time range [ns]
  bool is_chunk = false;
  Compression compression = Compression::kNone;
  uint64_t uncompressed_size = 0;
  uint32_t crc = 0;
  std::span<const uint8_t> records;  // stored (maybe compressed) records
};

std::string Str(std::string_view s) {
  return std::string(s);
}

bool SameSchema(const Schema& a, const Schema& b) {
  return a.name == b.name && a.encoding == b.encoding && a.data == b.data;
}
bool SameChannel(const Channel& a, const Channel& b) {
  return a.schema_id == b.schema_id && a.topic == b.topic &&
         a.message_encoding == b.message_encoding && a.metadata == b.metadata;
}

}  // namespace

struct McapReader::Impl {
  std::string name;  // the path, or what the caller called the buffer
  std::unique_ptr<Storage> storage;
  std::span<const uint8_t> file;

  Header header;
  std::map<uint16_t, Schema> schemas;
  std::map<uint16_t, Channel> channels;
  std::optional<Statistics> statistics;
  std::vector<ChunkInfo> chunks;
  std::vector<Segment> segments;  // file order
  bool has_summary = false;
  std::optional<Truncation> truncation;
  bool definitions_complete = false;  // every chunk was searched for Schema/Channel records

  std::optional<uint64_t> data_end;  // offset of the Data End record
  uint64_t data_end_next = 0;        // and of the byte after it
  uint32_t data_section_crc = 0;

  Error Fail(ErrorCode code, const std::string& what) const { return {code, name + ": " + what}; }
  Error Corrupt(const std::string& what) const { return Fail(ErrorCode::kDataLoss, what); }

  Status Parse();
  Status ScanData(uint64_t pos, uint64_t limit);
  Status ParseChunkHeader(uint64_t offset, std::span<const uint8_t> content, uint64_t length);
  Status ParseSummary(uint64_t start, uint64_t end, uint64_t offsets_end);
  Status CheckDataCrc();
  Status FindDefinitions();
  Status Define(uint8_t op, std::span<const uint8_t> content, uint64_t offset);
  Status ChunkRecords(const Segment& s, Decompressor& dec, std::vector<uint8_t>& buf,
                      std::span<const uint8_t>* records) const;
};

McapReader::McapReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
McapReader::McapReader(McapReader&&) noexcept = default;
McapReader& McapReader::operator=(McapReader&&) noexcept = default;
McapReader::~McapReader() = default;

const Header& McapReader::header() const {
  return impl_->header;
}
const std::map<uint16_t, Schema>& McapReader::schemas() const {
  return impl_->schemas;
}
const std::map<uint16_t, Channel>& McapReader::channels() const {
  return impl_->channels;
}
const std::optional<Statistics>& McapReader::statistics() const {
  return impl_->statistics;
}
const std::vector<ChunkInfo>& McapReader::chunks() const {
  return impl_->chunks;
}
bool McapReader::has_summary() const {
  return impl_->has_summary;
}
const std::optional<Truncation>& McapReader::truncation() const {
  return impl_->truncation;
}
uint64_t McapReader::file_size() const {
  return impl_->file.size();
}

Result<McapReader> McapReader::OpenFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    return Error{err == ENOENT   ? ErrorCode::kNotFound
                 : err == EACCES ? ErrorCode::kPermissionDenied
                                 : ErrorCode::kUnavailable,
                 Format("cannot open the recording %s: %s", path.c_str(), std::strerror(err))};
  }
  struct stat st;
  if (::fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    return Error{ErrorCode::kUnavailable,
                 Format("%s: fstat: %s", path.c_str(), std::strerror(err))};
  }
  auto impl = std::make_unique<Impl>();
  impl->name = path;
  if (st.st_size > 0) {
    void* addr = ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
    const int err = errno;
    ::close(fd);
    if (addr == MAP_FAILED) {
      return Error{ErrorCode::kUnavailable,
                   Format("%s: cannot map its %lld bytes: %s", path.c_str(),
                          static_cast<long long>(st.st_size), std::strerror(err))};
    }
    impl->storage = std::make_unique<MappedStorage>(addr, static_cast<size_t>(st.st_size));
  } else {
    ::close(fd);
    impl->storage = std::make_unique<VectorStorage>(std::vector<uint8_t>());
  }
  return Open(std::move(impl));
}

Result<McapReader> McapReader::OpenBuffer(std::vector<uint8_t> bytes, std::string name) {
  auto impl = std::make_unique<Impl>();
  impl->name = std::move(name);
  impl->storage = std::make_unique<VectorStorage>(std::move(bytes));
  return Open(std::move(impl));
}

Result<McapReader> McapReader::OpenView(std::span<const uint8_t> bytes, std::string name) {
  auto impl = std::make_unique<Impl>();
  impl->name = std::move(name);
  impl->storage = std::make_unique<Storage>();
  impl->storage->bytes = bytes;
  return Open(std::move(impl));
}

Result<McapReader> McapReader::Open(std::unique_ptr<Impl> impl) {
  impl->file = impl->storage->bytes;
  if (Status s = impl->Parse(); !s.ok()) return s.error();
  return McapReader(std::move(impl));
}

Status McapReader::Impl::Parse() {
  const uint64_t size = file.size();
  if (size == 0) return Corrupt("the file is empty (0 bytes): the recording wrote nothing");
  if (size < sizeof kMagic || std::memcmp(file.data(), kMagic, sizeof kMagic) != 0) {
    if (size < sizeof kMagic && std::memcmp(file.data(), kMagic, size) == 0) {
      return Corrupt(Format("the file is %llu bytes, cut inside the 8-byte MCAP magic", ull(size)));
    }
    return Fail(
        ErrorCode::kInvalidArgument,
        "not an MCAP file (it does not start with the magic bytes 89 4D 43 41 50 30 0D 0A)");
  }

  // The Header record.
  uint64_t pos = sizeof kMagic;
  if (size - pos < kRecordPrefix) {
    truncation = Truncation{
        pos, Format("the file is %llu bytes: it ends before the Header record", ull(size))};
    return Status::Ok();
  }
  if (file[pos] != kOpHeader) {
    return Corrupt(Format("the first record is a %s, not a Header", OpcodeName(file[pos]).c_str()));
  }
  const uint64_t header_len = LoadU64(file.data() + pos + 1);
  if (header_len > size - pos - kRecordPrefix) {
    truncation = Truncation{pos, Format("the Header record at offset %llu is cut", ull(pos))};
    return Status::Ok();
  }
  FieldReader hr(file.subspan(pos + kRecordPrefix, header_len));
  header.profile = Str(hr.String());
  header.library = Str(hr.String());
  if (!hr.ok()) return Corrupt("the Header record's fields overrun it");
  pos += kRecordPrefix + header_len;

  // A footer, if the file ends with one: 0x02, length 20, three fields, then the magic.
  bool footer = false;
  uint64_t summary_start = 0, summary_offset_start = 0;
  uint32_t summary_crc = 0;
  const uint64_t footer_at = size - kFooterRecord - sizeof kMagic;
  if (size >= pos + kFooterRecord + sizeof kMagic &&
      std::memcmp(file.data() + size - sizeof kMagic, kMagic, sizeof kMagic) == 0 &&
      file[footer_at] == kOpFooter && LoadU64(file.data() + footer_at + 1) == kFooterContent) {
    footer = true;
    summary_start = LoadU64(file.data() + footer_at + 9);
    summary_offset_start = LoadU64(file.data() + footer_at + 17);
    summary_crc = LoadU32(file.data() + footer_at + 25);
    if ((summary_start != 0 && (summary_start < pos || summary_start > footer_at)) ||
        (summary_offset_start != 0 && (summary_offset_start < std::max(pos, summary_start) ||
                                       summary_offset_start > footer_at))) {
      return Corrupt(
          Format("the footer's summary offsets (%llu, %llu) are outside the file's %llu "
                 "bytes before the footer",
                 ull(summary_start), ull(summary_offset_start), ull(footer_at)));
    }
  }

  const uint64_t data_limit = !footer                     ? size
                              : summary_start != 0        ? summary_start
                              : summary_offset_start != 0 ? summary_offset_start
                                                          : footer_at;
  if (Status s = ScanData(pos, data_limit); !s.ok()) return s;

  if (footer) {
    if (summary_crc != 0) {
      const uint64_t from = summary_start != 0          ? summary_start
                            : summary_offset_start != 0 ? summary_offset_start
                                                        : footer_at;
      const uint32_t crc = Crc32(0, file.subspan(from, footer_at + 25 - from));
      if (crc != summary_crc) {
        return Corrupt(
            Format("summary CRC mismatch (footer says 0x%08x, the bytes from offset %llu "
                   "give 0x%08x): the summary or the footer is corrupt",
                   summary_crc, ull(from), crc));
      }
    }
    if (summary_start != 0) {
      const uint64_t end = summary_offset_start != 0 ? summary_offset_start : footer_at;
      if (Status s = ParseSummary(summary_start, end, footer_at); !s.ok()) return s;
    }
  } else if (!truncation) {
    const uint64_t valid = data_end ? data_end_next : size;
    truncation = Truncation{valid, data_end ? Format("the file ends after its Data End record at "
                                                     "offset %llu, without the summary and footer",
                                                     ull(*data_end))
                                            : Format("the file ends after a whole record at offset "
                                                     "%llu, without Data End record or footer (the "
                                                     "recording was not closed)",
                                                     ull(size))};
  }
  return CheckDataCrc();
}

Status McapReader::Impl::ScanData(uint64_t pos, uint64_t limit) {
  constexpr size_t kNone = SIZE_MAX;
  size_t loose = kNone;  // index in `segments` of the open run of records outside chunks
  uint64_t loose_end = 0;
  while (pos < limit) {
    const uint64_t left = limit - pos;
    if (left < kRecordPrefix) {
      truncation =
          Truncation{pos, Format("the file ends %llu bytes into the record at offset %llu, "
                                 "inside its 9-byte opcode and length",
                                 ull(left), ull(pos))};
      return Status::Ok();
    }
    const uint8_t op = file[pos];
    const uint64_t len = LoadU64(file.data() + pos + 1);
    if (len > left - kRecordPrefix) {
      const uint64_t have = left - kRecordPrefix;
      Truncation t{pos, Format("the %s record at offset %llu is cut: %llu of its %llu bytes are "
                               "present",
                               OpcodeName(op).c_str(), ull(pos), ull(have), ull(len))};
      if (limit != file.size()) {
        return Corrupt(
            Format("the %s record at offset %llu (%llu bytes) runs past the data section, "
                   "which the footer ends at %llu",
                   OpcodeName(op).c_str(), ull(pos), ull(len), ull(limit)));
      }
      truncation = std::move(t);
      return Status::Ok();
    }
    const std::span<const uint8_t> content = file.subspan(pos + kRecordPrefix, len);
    const uint64_t next = pos + kRecordPrefix + len;
    switch (op) {
      case kOpSchema:
      case kOpChannel:
        if (Status s = Define(op, content, pos); !s.ok()) return s;
        if (loose != kNone && loose_end == pos) {
          segments[loose].records =
              file.subspan(segments[loose].offset, next - segments[loose].offset);
          loose_end = next;
        }
        break;
      case kOpMessage: {
        if (len < kMessageFixed) {
          return Corrupt(
              Format("the Message record at offset %llu is %llu bytes, under the %zu of "
                     "its fixed fields",
                     ull(pos), ull(len), kMessageFixed));
        }
        const uint64_t t = LoadU64(content.data() + 6);
        if (loose == kNone || loose_end != pos) {
          loose = segments.size();
          segments.push_back(Segment{});
          segments[loose].offset = pos;
          segments[loose].start_time = segments[loose].end_time = t;
        }
        Segment& run = segments[loose];
        run.start_time = std::min(run.start_time, t);
        run.end_time = std::max(run.end_time, t);
        run.records = file.subspan(run.offset, next - run.offset);
        loose_end = next;
        break;
      }
      case kOpChunk:
        if (Status s = ParseChunkHeader(pos, content, kRecordPrefix + len); !s.ok()) return s;
        break;
      case kOpDataEnd: {
        FieldReader r(content);
        data_section_crc = r.U32();
        if (!r.ok()) {
          return Corrupt(Format("the Data End record at offset %llu is %llu bytes, under 4",
                                ull(pos), ull(len)));
        }
        data_end = pos;
        data_end_next = next;
        return Status::Ok();
      }
      case kOpHeader: return Corrupt(Format("a second Header record at offset %llu", ull(pos)));
      case kOpFooter:
        return Corrupt(
            Format("a Footer record at offset %llu, before the end of the file", ull(pos)));
      case kOpChunkIndex:
      case kOpAttachmentIndex:
      case kOpStatistics:
      case kOpMetadataIndex:
      case kOpSummaryOffset:
        // Summary records without a Data End before them: the data section ended here.
        return Status::Ok();
      default:
        // Message Index, Attachment, Metadata and opcodes from later versions: not needed here.
        break;
    }
    if (op != kOpMessage && op != kOpSchema && op != kOpChannel) loose = kNone;
    pos = next;
  }
  return Status::Ok();
}

Status McapReader::Impl::Define(uint8_t op, std::span<const uint8_t> content, uint64_t offset) {
  FieldReader r(content);
  if (op == kOpSchema) {
    Schema s;
    s.id = r.U16();
    s.name = Str(r.String());
    s.encoding = Str(r.String());
    auto data = r.Bytes(r.U32());
    if (!r.ok()) return Corrupt(Format("the Schema record at offset %llu overruns", ull(offset)));
    if (s.id == 0) return Status::Ok();  // the spec: an id of 0 is invalid and ignored
    s.data.assign(data.begin(), data.end());
    auto [it, added] = schemas.try_emplace(s.id, s);
    if (!added && !SameSchema(it->second, s)) {
      return Corrupt(Format("schema %u is defined twice, differently (again at offset %llu)", s.id,
                            ull(offset)));
    }
    return Status::Ok();
  }
  Channel c;
  c.id = r.U16();
  c.schema_id = r.U16();
  c.topic = Str(r.String());
  c.message_encoding = Str(r.String());
  FieldReader m(r.Bytes(r.U32()));
  while (r.ok() && m.ok() && m.remaining() > 0) {
    std::string key = Str(m.String());
    std::string value = Str(m.String());
    c.metadata[std::move(key)] = std::move(value);
  }
  if (!r.ok() || !m.ok()) {
    return Corrupt(Format("the Channel record at offset %llu overruns", ull(offset)));
  }
  auto [it, added] = channels.try_emplace(c.id, c);
  if (!added && !SameChannel(it->second, c)) {
    return Corrupt(Format("channel %u (%s) is defined twice, differently (again at offset %llu)",
                          c.id, c.topic.c_str(), ull(offset)));
  }
  return Status::Ok();
}

Status McapReader::Impl::ParseChunkHeader(uint64_t offset, std::span<const uint8_t> content,
                                          uint64_t length) {
  FieldReader r(content);
  ChunkInfo c;
  c.offset = offset;
  c.length = length;
  c.message_start_time = r.U64();
  c.message_end_time = r.U64();
  c.uncompressed_size = r.U64();
  c.uncompressed_crc = r.U32();
  const std::string_view compression = r.String();
  const uint64_t stored = r.U64();
  auto records = r.Bytes(stored);
  if (!r.ok()) {
    return Corrupt(Format("the Chunk record at offset %llu: its fields overrun its %llu bytes",
                          ull(offset), ull(content.size())));
  }
  if (compression.empty()) {
    c.compression = Compression::kNone;
  } else if (compression == "zstd") {
    c.compression = Compression::kZstd;
  } else if (compression == "lz4") {
    c.compression = Compression::kLz4;
  } else {
    return Fail(ErrorCode::kUnimplemented,
                Format("the Chunk record at offset %llu uses compression '%.*s'; this reader "
                       "reads '', 'zstd' and 'lz4'",
                       ull(offset), static_cast<int>(compression.size()), compression.data()));
  }
  c.compressed_size = stored;
  if (c.uncompressed_size > kMaxChunkBytes) {
    return Corrupt(
        Format("the Chunk record at offset %llu claims %llu bytes uncompressed, over "
               "the %llu-byte limit",
               ull(offset), ull(c.uncompressed_size), ull(kMaxChunkBytes)));
  }
  if (c.compression == Compression::kNone && c.uncompressed_size != stored) {
    return Corrupt(
        Format("the uncompressed Chunk record at offset %llu stores %llu bytes of "
               "records but says %llu",
               ull(offset), ull(stored), ull(c.uncompressed_size)));
  }
  if (c.message_start_time > c.message_end_time) {
    return Corrupt(
        Format("the Chunk record at offset %llu starts at log time %llu, after its end "
               "%llu",
               ull(offset), ull(c.message_start_time), ull(c.message_end_time)));
  }
  chunks.push_back(c);
  Segment s;
  s.offset = offset;
  s.start_time = c.message_start_time;
  s.end_time = c.message_end_time;
  s.is_chunk = true;
  s.compression = c.compression;
  s.uncompressed_size = c.uncompressed_size;
  s.crc = c.uncompressed_crc;
  s.records = records;
  segments.push_back(s);
  return Status::Ok();
}

Status McapReader::Impl::ParseSummary(uint64_t start, uint64_t end, uint64_t offsets_end) {
  has_summary = true;
  struct IndexedChunk {
    uint64_t offset, length, compressed, uncompressed;
  };
  std::vector<IndexedChunk> indexed;
  for (uint64_t pos = start; pos < end;) {
    if (end - pos < kRecordPrefix || LoadU64(file.data() + pos + 1) > end - pos - kRecordPrefix) {
      return Corrupt(Format("the summary record at offset %llu runs past the summary's end at %llu",
                            ull(pos), ull(end)));
    }
    const uint8_t op = file[pos];
    const uint64_t len = LoadU64(file.data() + pos + 1);
    const std::span<const uint8_t> content = file.subspan(pos + kRecordPrefix, len);
    FieldReader r(content);
    switch (op) {
      case kOpSchema:
      case kOpChannel:
        if (Status s = Define(op, content, pos); !s.ok()) return s;
        break;
      case kOpChunkIndex: {
        IndexedChunk c;
        r.U64();  // start and end times: the chunk's own header is what the cursor uses
        r.U64();
        c.offset = r.U64();
        c.length = r.U64();
        r.Bytes(r.U32());  // message index offsets
        r.U64();           // message index length
        r.String();        // compression
        c.compressed = r.U64();
        c.uncompressed = r.U64();
        if (!r.ok())
          return Corrupt(Format("the Chunk Index record at offset %llu overruns", ull(pos)));
        indexed.push_back(c);
        break;
      }
      case kOpStatistics: {
        Statistics st;
        st.message_count = r.U64();
        st.schema_count = r.U16();
        st.channel_count = r.U32();
        st.attachment_count = r.U32();
        st.metadata_count = r.U32();
        st.chunk_count = r.U32();
        st.message_start_time = r.U64();
        st.message_end_time = r.U64();
        FieldReader m(r.Bytes(r.U32()));
        while (r.ok() && m.ok() && m.remaining() > 0) {
          const uint16_t id = m.U16();
          st.channel_message_counts[id] = m.U64();
        }
        if (!r.ok() || !m.ok()) {
          return Corrupt(Format("the Statistics record at offset %llu overruns", ull(pos)));
        }
        statistics = std::move(st);
        break;
      }
      default: break;  // Attachment/Metadata Index and later records
    }
    pos += kRecordPrefix + len;
  }
  // Summary Offset records must point into the summary.
  for (uint64_t pos = end; pos < offsets_end;) {
    if (offsets_end - pos < kRecordPrefix ||
        LoadU64(file.data() + pos + 1) > offsets_end - pos - kRecordPrefix) {
      return Corrupt(
          Format("the summary offset record at offset %llu runs into the footer", ull(pos)));
    }
    const uint64_t len = LoadU64(file.data() + pos + 1);
    if (file[pos] == kOpSummaryOffset) {
      FieldReader r(file.subspan(pos + kRecordPrefix, len));
      r.U8();
      const uint64_t group_start = r.U64();
      const uint64_t group_length = r.U64();
      if (!r.ok() || group_start < start || group_length > end - start ||
          group_start - start > end - start - group_length) {
        return Corrupt(Format("the Summary Offset record at offset %llu points outside the summary",
                              ull(pos)));
      }
    }
    pos += kRecordPrefix + len;
  }

  // Every Chunk Index must name a chunk the scan found, and the other way round.
  if (!indexed.empty()) {
    if (indexed.size() != chunks.size()) {
      return Corrupt(Format("the summary indexes %zu chunks but the data section holds %zu",
                            indexed.size(), chunks.size()));
    }
    std::sort(indexed.begin(), indexed.end(),
              [](const IndexedChunk& a, const IndexedChunk& b) { return a.offset < b.offset; });
    for (size_t i = 0; i < indexed.size(); ++i) {
      const IndexedChunk& x = indexed[i];
      const ChunkInfo& c = chunks[i];
      if (x.offset != c.offset || x.length != c.length || x.compressed != c.compressed_size ||
          x.uncompressed != c.uncompressed_size) {
        return Corrupt(
            Format("the Chunk Index for offset %llu (%llu bytes) does not match the "
                   "chunk the data section has at offset %llu (%llu bytes)",
                   ull(x.offset), ull(x.length), ull(c.offset), ull(c.length)));
      }
    }
  }
  if (statistics && statistics->chunk_count != chunks.size()) {
    return Corrupt(Format("the Statistics count %u chunks but the data section holds %zu",
                          statistics->chunk_count, chunks.size()));
  }
  return Status::Ok();
}

Status McapReader::Impl::ChunkRecords(const Segment& s, Decompressor& dec,
                                      std::vector<uint8_t>& buf,
                                      std::span<const uint8_t>* records) const {
  if (!s.is_chunk || s.compression == Compression::kNone) {
    *records = s.records;
  } else {
    if (Status st = dec.Decompress(s.compression, s.records, s.uncompressed_size, buf); !st.ok()) {
      return Corrupt(Format("the Chunk record at offset %llu does not decompress: %s",
                            ull(s.offset), st.error().message.c_str()));
    }
    *records = buf;
  }
  if (s.is_chunk && s.crc != 0) {
    const uint32_t crc = Crc32(0, *records);
    if (crc != s.crc) {
      return Corrupt(
          Format("CRC mismatch in the Chunk record at offset %llu: it stores 0x%08x, "
                 "its records give 0x%08x",
                 ull(s.offset), s.crc, crc));
    }
  }
  return Status::Ok();
}

Status McapReader::Impl::CheckDataCrc() {
  if (!data_end || data_section_crc == 0) return Status::Ok();
  const uint32_t crc = Crc32(0, file.first(*data_end));
  if (crc == data_section_crc) return Status::Ok();
  // Name the chunk that is corrupt, if one is.
  Decompressor dec;
  std::vector<uint8_t> buf;
  for (const Segment& s : segments) {
    std::span<const uint8_t> records;
    if (Status st = ChunkRecords(s, dec, buf, &records); !st.ok()) return st;
  }
  return Corrupt(
      Format("data section CRC mismatch (Data End says 0x%08x, bytes 0 .. %llu give "
             "0x%08x); every chunk passes its own CRC, so the damage is in a record "
             "header or outside the chunks",
             data_section_crc, ull(*data_end), crc));
}

Status McapReader::Impl::FindDefinitions() {
  if (definitions_complete) return Status::Ok();
  definitions_complete = true;
  Decompressor dec;
  std::vector<uint8_t> buf;
  for (const Segment& s : segments) {
    if (!s.is_chunk) continue;
    std::span<const uint8_t> records;
    if (Status st = ChunkRecords(s, dec, buf, &records); !st.ok()) return st;
    for (size_t pos = 0; pos + kRecordPrefix <= records.size();) {
      const uint8_t op = records[pos];
      const uint64_t len = LoadU64(records.data() + pos + 1);
      if (len > records.size() - pos - kRecordPrefix) break;  // the cursor reports it
      if (op == kOpSchema || op == kOpChannel) {
        if (Status st = Define(op, records.subspan(pos + kRecordPrefix, len), s.offset); !st.ok()) {
          return st;
        }
      }
      pos += kRecordPrefix + static_cast<size_t>(len);
    }
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// The cursor

struct MessageCursor::State {
  McapReader::Impl* r = nullptr;
  std::vector<uint32_t> order;  // segment indices by (start time, offset)
  size_t next = 0;              // next segment in `order` to open

  struct Slot {
    std::vector<uint8_t> buf;          // decompressed records (capacity reused)
    std::span<const uint8_t> records;  // what the entries index into
    uint64_t segment_offset = 0;
    size_t remaining = 0;  // entries not yet returned
  };
  std::vector<Slot> slots;
  std::vector<uint32_t> free_slots;

  struct Entry {
    uint64_t log_time;
    uint64_t segment_offset;
    uint64_t pos;  // of the Message record in the slot's records
    const Channel* channel;
    uint32_t slot;
  };
  std::vector<Entry> heap;  // min-heap on (log_time, segment_offset, pos)

  Message current;
  uint32_t current_slot = UINT32_MAX;
  uint64_t returned = 0;
  std::optional<Error> error;
  Decompressor dec;

  static bool Later(const Entry& a, const Entry& b) {
    if (a.log_time != b.log_time) return a.log_time > b.log_time;
    if (a.segment_offset != b.segment_offset) return a.segment_offset > b.segment_offset;
    return a.pos > b.pos;
  }

  void Release(uint32_t slot) {
    slots[slot].records = {};
    free_slots.push_back(slot);
  }

  Status OpenSegment(const Segment& s);
  Result<const Channel*> Resolve(uint16_t channel_id, uint64_t segment_offset);
};

MessageCursor::MessageCursor(std::unique_ptr<State> state) : state_(std::move(state)) {}
MessageCursor::MessageCursor(MessageCursor&&) noexcept = default;
MessageCursor& MessageCursor::operator=(MessageCursor&&) noexcept = default;
MessageCursor::~MessageCursor() = default;

MessageCursor McapReader::Messages() {
  auto st = std::make_unique<MessageCursor::State>();
  st->r = impl_.get();
  st->order.resize(impl_->segments.size());
  for (uint32_t i = 0; i < st->order.size(); ++i) st->order[i] = i;
  const auto& segs = impl_->segments;
  std::sort(st->order.begin(), st->order.end(), [&](uint32_t a, uint32_t b) {
    if (segs[a].start_time != segs[b].start_time) return segs[a].start_time < segs[b].start_time;
    return segs[a].offset < segs[b].offset;
  });
  return MessageCursor(std::move(st));
}

Status McapReader::ForEachMessage(const std::function<Status(const Message&)>& fn) {
  MessageCursor cursor = Messages();
  for (;;) {
    auto m = cursor.Next();
    if (!m.ok()) return m.error();
    if (*m == nullptr) return Status::Ok();
    if (Status s = fn(**m); !s.ok()) return s;
  }
}

Result<const Channel*> MessageCursor::State::Resolve(uint16_t channel_id, uint64_t segment_offset) {
  auto it = r->channels.find(channel_id);
  if (it == r->channels.end()) {
    // A file without a summary may define channels inside chunks later in the file.
    if (Status s = r->FindDefinitions(); !s.ok()) return s.error();
    it = r->channels.find(channel_id);
    if (it == r->channels.end()) {
      return r->Corrupt(
          Format("a message in the chunk at offset %llu is on channel %u, which no "
                 "Channel record defines",
                 ull(segment_offset), channel_id));
    }
  }
  const Channel& c = it->second;
  if (c.schema_id != 0 && r->schemas.count(c.schema_id) == 0) {
    if (Status s = r->FindDefinitions(); !s.ok()) return s.error();
    if (r->schemas.count(c.schema_id) == 0) {
      return r->Corrupt(Format("channel %u (%s) uses schema %u, which no Schema record defines",
                               c.id, c.topic.c_str(), c.schema_id));
    }
  }
  return &c;
}

Status MessageCursor::State::OpenSegment(const Segment& s) {
  uint32_t slot;
  if (!free_slots.empty()) {
    slot = free_slots.back();
    free_slots.pop_back();
  } else {
    slot = static_cast<uint32_t>(slots.size());
    slots.emplace_back();
  }
  Slot& sl = slots[slot];
  sl.segment_offset = s.offset;
  sl.remaining = 0;
  if (Status st = r->ChunkRecords(s, dec, sl.buf, &sl.records); !st.ok()) {
    Release(slot);
    return st;
  }
  const std::span<const uint8_t> records = sl.records;
  for (size_t pos = 0; pos < records.size();) {
    if (records.size() - pos < kRecordPrefix ||
        LoadU64(records.data() + pos + 1) > records.size() - pos - kRecordPrefix) {
      Release(slot);
      return r->Corrupt(
          Format("in the chunk at offset %llu, the record at %zu of its %zu bytes "
                 "runs past its end",
                 ull(s.offset), pos, records.size()));
    }
    const uint8_t op = records[pos];
    const uint64_t len = LoadU64(records.data() + pos + 1);
    const std::span<const uint8_t> content = records.subspan(pos + kRecordPrefix, len);
    if (op == kOpMessage) {
      if (len < kMessageFixed) {
        Release(slot);
        return r->Corrupt(
            Format("in the chunk at offset %llu, the Message record at %zu is %llu "
                   "bytes, under its %zu fixed",
                   ull(s.offset), pos, ull(len), kMessageFixed));
      }
      const uint16_t channel_id = LoadU16(content.data());
      const uint64_t log_time = LoadU64(content.data() + 6);
      if (s.is_chunk && (log_time < s.start_time || log_time > s.end_time)) {
        Release(slot);
        return r->Corrupt(
            Format("in the chunk at offset %llu, a message at log time %llu lies "
                   "outside the chunk's range %llu .. %llu",
                   ull(s.offset), ull(log_time), ull(s.start_time), ull(s.end_time)));
      }
      auto channel = Resolve(channel_id, s.offset);
      if (!channel.ok()) {
        Release(slot);
        return channel.error();
      }
      heap.push_back({log_time, s.offset, pos, *channel, slot});
      std::push_heap(heap.begin(), heap.end(), Later);
      ++sl.remaining;
    } else if (s.is_chunk && (op == kOpSchema || op == kOpChannel)) {
      if (Status st = r->Define(op, content, s.offset); !st.ok()) {
        Release(slot);
        return st;
      }
    }
    pos += kRecordPrefix + static_cast<size_t>(len);
  }
  if (sl.remaining == 0) Release(slot);
  return Status::Ok();
}

Result<const Message*> MessageCursor::Next() {
  State& c = *state_;
  if (c.error) return *c.error;
  if (c.current_slot != UINT32_MAX) {
    if (c.slots[c.current_slot].remaining == 0) c.Release(c.current_slot);
    c.current_slot = UINT32_MAX;
  }
  const auto& segs = c.r->segments;
  // Open every segment that could hold a message earlier than the earliest one pending.
  while (c.next < c.order.size() &&
         (c.heap.empty() || segs[c.order[c.next]].start_time <= c.heap.front().log_time)) {
    if (Status s = c.OpenSegment(segs[c.order[c.next++]]); !s.ok()) {
      c.error = s.error();
      return s.error();
    }
  }
  if (c.heap.empty()) {
    const auto& stats = c.r->statistics;
    if (stats && !c.r->truncation && stats->message_count != c.returned) {
      c.error = c.r->Corrupt(Format("the Statistics count %llu messages but the chunks hold %llu",
                                    ull(stats->message_count), ull(c.returned)));
      return *c.error;
    }
    return static_cast<const Message*>(nullptr);
  }
  std::pop_heap(c.heap.begin(), c.heap.end(), State::Later);
  const State::Entry e = c.heap.back();
  c.heap.pop_back();
  State::Slot& sl = c.slots[e.slot];
  const size_t len = static_cast<size_t>(LoadU64(sl.records.data() + e.pos + 1));
  const uint8_t* p = sl.records.data() + e.pos + kRecordPrefix;
  Message& m = c.current;
  m.channel = e.channel;
  if (e.channel->schema_id == 0) {
    m.schema = nullptr;
  } else {
    m.schema = &c.r->schemas.find(e.channel->schema_id)->second;
  }
  m.sequence = LoadU32(p + 2);
  m.log_time = e.log_time;
  m.publish_time = LoadU64(p + 14);
  m.data = {p + kMessageFixed, len - kMessageFixed};
  m.chunk_offset = e.segment_offset;
  --sl.remaining;
  c.current_slot = e.slot;
  ++c.returned;
  return static_cast<const Message*>(&m);
}

}  // namespace rheo::record
