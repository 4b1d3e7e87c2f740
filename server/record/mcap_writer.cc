// McapWriter: buffers messages into a chunk, then compresses and writes it with its Message Index
// records, and writes the summary at Close. Every byte goes through Emit(), which keeps the file
// offset and the running CRC the Data End and Footer records need.
#include <algorithm>

#include "common/format.h"
#include "record/mcap.h"
#include "record/mcap_format.h"

namespace rheo::record {

using namespace internal;  // NOLINT: the wire-format helpers of this library

namespace {

using ull = unsigned long long;

/// A Message Index entry: a message's log time and its offset in the uncompressed chunk.
struct IndexEntry {
  uint64_t log_time;
  uint64_t offset;
};

struct ChannelState {
  uint64_t message_count = 0;
  std::vector<IndexEntry> index;  // this chunk's entries; capacity kept across chunks
  bool sorted = true;             // entries in log-time order so far
};

/// What the summary's Chunk Index record for one chunk needs.
struct ChunkIndexEntry {
  uint64_t start_time, end_time;
  uint64_t offset, length;
  uint64_t index_length;
  uint64_t compressed_size, uncompressed_size;
  size_t index_offsets_begin, index_offsets_end;  // into Impl::index_offsets
};

/// Starts a record in `b`: opcode and a length placeholder. @return where the length goes.
size_t BeginRecord(std::vector<uint8_t>& b, uint8_t op) {
  PutU8(b, op);
  const size_t at = b.size();
  PutU64(b, 0);
  return at;
}
void EndRecord(std::vector<uint8_t>& b, size_t at) {
  PatchU64(b, at, b.size() - at - 8);
}

}  // namespace

struct McapWriter::Impl {
  enum class State { kIdle, kOpen, kClosed, kFailed };

  ByteSink* sink = nullptr;
  WriterOptions options;
  State state = State::kIdle;
  Status failure;       // the sticky error once kFailed
  uint64_t offset = 0;  // bytes handed to the sink [bytes]
  uint32_t crc = 0;     // CRC of the data section, then (from the summary on) of the summary
  std::unique_ptr<Compressor> compressor;

  // Definitions, kept serialized for the summary.
  uint16_t schema_count = 0;
  std::vector<uint8_t> schema_records;
  std::vector<ChannelState> channels;  // [channel id - 1]
  std::vector<uint8_t> channel_records;

  // The open chunk.
  std::vector<uint8_t> chunk;               // uncompressed records
  std::vector<uint16_t> chunk_channels;     // channels with messages in it, in first-use order
  uint64_t chunk_start = 0, chunk_end = 0;  // log-time range [ns]
  uint32_t chunk_messages = 0;

  // The file so far.
  std::vector<ChunkIndexEntry> chunk_indexes;
  std::vector<std::pair<uint16_t, uint64_t>> index_offsets;  // channel id, Message Index offset
  uint64_t message_count = 0;
  uint64_t start_time = 0, end_time = 0;  // [ns]

  std::vector<uint8_t> scratch;  // record headers, index records, the summary

  Status Fail(const std::string& what, const Status& s) {
    state = State::kFailed;
    failure = Error{s.error().code, what + ": " + s.error().message};
    return failure;
  }

  Status Usable() const {
    switch (state) {
      case State::kOpen: return Status::Ok();
      case State::kIdle: return FailedPrecondition("the MCAP writer is not open (call Open first)");
      case State::kClosed: return FailedPrecondition("the MCAP writer is already closed");
      case State::kFailed: return failure;
    }
    return Internal("bad writer state");
  }

  // Hands bytes to the sink, advancing the offset and the CRC.
  Status Emit(std::span<const uint8_t> bytes, const char* what) {
    Status s = sink->Write(bytes);
    if (!s.ok()) return Fail(Format("writing the %s at offset %llu", what, ull(offset)), s);
    offset += bytes.size();
    crc = Crc32(crc, bytes);
    return Status::Ok();
  }

  Status CloseChunk();
};

McapWriter::McapWriter() : impl_(std::make_unique<Impl>()) {}
McapWriter::~McapWriter() = default;

bool McapWriter::is_open() const {
  return impl_->state == Impl::State::kOpen;
}
uint64_t McapWriter::bytes_written() const {
  return impl_->offset;
}
uint64_t McapWriter::message_count() const {
  return impl_->message_count;
}
uint32_t McapWriter::chunk_count() const {
  return static_cast<uint32_t>(impl_->chunk_indexes.size());
}

Status McapWriter::Open(ByteSink& sink, std::string_view profile, std::string_view library,
                        const WriterOptions& options) {
  Impl& w = *impl_;
  if (w.state != Impl::State::kIdle) {
    return FailedPrecondition("McapWriter::Open: the writer was opened before (one file each)");
  }
  if (options.chunk_size < 1 || options.chunk_size > kMaxChunkBytes) {
    return InvalidArgument(Format("chunk_size %llu is outside 1 .. %llu bytes",
                                  ull(options.chunk_size), ull(kMaxChunkBytes)));
  }
  auto compressor = MakeCompressor(options.compression, options.zstd_level);
  if (!compressor.ok()) return compressor.error();
  w.compressor = std::move(compressor).value();
  w.options = options;
  w.sink = &sink;
  w.state = Impl::State::kOpen;

  w.scratch.clear();
  PutBytes(w.scratch, kMagic);
  const size_t at = BeginRecord(w.scratch, kOpHeader);
  PutString(w.scratch, profile);
  PutString(w.scratch, library);
  EndRecord(w.scratch, at);
  return w.Emit(w.scratch, "magic and Header");
}

Result<uint16_t> McapWriter::AddSchema(std::string_view name, std::string_view encoding,
                                       std::span<const uint8_t> data) {
  Impl& w = *impl_;
  if (Status s = w.Usable(); !s.ok()) return s.error();
  if (name.empty()) return InvalidArgument("AddSchema: the schema name is empty");
  if (encoding.empty() && !data.empty()) {
    return InvalidArgument(Format("AddSchema(%.*s): data without an encoding (the spec wants none)",
                                  static_cast<int>(name.size()), name.data()));
  }
  if (w.schema_count == UINT16_MAX) {
    return ResourceExhausted("AddSchema: a file holds at most 65535 schemas");
  }
  const uint16_t id = ++w.schema_count;
  w.scratch.clear();
  const size_t at = BeginRecord(w.scratch, kOpSchema);
  PutU16(w.scratch, id);
  PutString(w.scratch, name);
  PutString(w.scratch, encoding);
  PutU32(w.scratch, static_cast<uint32_t>(data.size()));
  PutBytes(w.scratch, data);
  EndRecord(w.scratch, at);
  PutBytes(w.schema_records, w.scratch);
  if (Status s = w.Emit(w.scratch, "Schema record"); !s.ok()) return s.error();
  return id;
}

Result<uint16_t> McapWriter::AddChannel(uint16_t schema_id, std::string_view topic,
                                        std::string_view message_encoding,
                                        const std::map<std::string, std::string>& metadata) {
  Impl& w = *impl_;
  if (Status s = w.Usable(); !s.ok()) return s.error();
  if (topic.empty()) return InvalidArgument("AddChannel: the topic is empty");
  if (message_encoding.empty()) {
    return InvalidArgument(Format("AddChannel(%.*s): the message encoding is empty",
                                  static_cast<int>(topic.size()), topic.data()));
  }
  if (schema_id > w.schema_count) {
    return InvalidArgument(Format("AddChannel(%.*s): schema %u was not added (%u schemas so far)",
                                  static_cast<int>(topic.size()), topic.data(), schema_id,
                                  w.schema_count));
  }
  if (w.channels.size() == UINT16_MAX) {
    return ResourceExhausted("AddChannel: a file holds at most 65535 channels");
  }
  const uint16_t id = static_cast<uint16_t>(w.channels.size() + 1);
  w.scratch.clear();
  const size_t at = BeginRecord(w.scratch, kOpChannel);
  PutU16(w.scratch, id);
  PutU16(w.scratch, schema_id);
  PutString(w.scratch, topic);
  PutString(w.scratch, message_encoding);
  const size_t map_at = w.scratch.size();
  PutU32(w.scratch, 0);
  for (const auto& [key, value] : metadata) {
    PutString(w.scratch, key);
    PutString(w.scratch, value);
  }
  const uint32_t map_len = static_cast<uint32_t>(w.scratch.size() - map_at - 4);
  for (int i = 0; i < 4; ++i) w.scratch[map_at + i] = uint8_t(map_len >> (8 * i));
  EndRecord(w.scratch, at);
  w.channels.emplace_back();
  PutBytes(w.channel_records, w.scratch);
  if (Status s = w.Emit(w.scratch, "Channel record"); !s.ok()) return s.error();
  return id;
}

Status McapWriter::Write(uint16_t channel_id, uint32_t sequence, uint64_t log_time_ns,
                         uint64_t publish_time_ns, std::span<const uint8_t> data) {
  Impl& w = *impl_;
  if (Status s = w.Usable(); !s.ok()) return s;
  if (channel_id == 0 || channel_id > w.channels.size()) {
    return InvalidArgument(Format("Write: channel %u was not added (%zu channels so far)",
                                  channel_id, w.channels.size()));
  }
  const uint64_t record = kRecordPrefix + kMessageFixed + data.size();
  if (record > kMaxChunkBytes) {
    return ResourceExhausted(Format("Write: a %zu-byte message is over the %llu-byte chunk limit",
                                    data.size(), ull(kMaxChunkBytes)));
  }
  if (!w.chunk.empty() && w.chunk.size() + record > kMaxChunkBytes) {
    if (Status s = w.CloseChunk(); !s.ok()) return s;
  }

  ChannelState& ch = w.channels[channel_id - 1];
  if (ch.index.empty()) {
    w.chunk_channels.push_back(channel_id);
    ch.sorted = true;
  } else if (log_time_ns < ch.index.back().log_time) {
    ch.sorted = false;
  }
  ch.index.push_back({log_time_ns, w.chunk.size()});
  ++ch.message_count;

  uint8_t head[kRecordPrefix + kMessageFixed];
  uint8_t* p = head;
  *p++ = kOpMessage;
  const uint64_t content = kMessageFixed + data.size();
  for (int i = 0; i < 8; ++i) *p++ = uint8_t(content >> (8 * i));
  *p++ = uint8_t(channel_id);
  *p++ = uint8_t(channel_id >> 8);
  for (int i = 0; i < 4; ++i) *p++ = uint8_t(sequence >> (8 * i));
  for (int i = 0; i < 8; ++i) *p++ = uint8_t(log_time_ns >> (8 * i));
  for (int i = 0; i < 8; ++i) *p++ = uint8_t(publish_time_ns >> (8 * i));
  w.chunk.insert(w.chunk.end(), head, head + sizeof head);
  w.chunk.insert(w.chunk.end(), data.begin(), data.end());

  if (w.chunk_messages == 0) {
    w.chunk_start = w.chunk_end = log_time_ns;
  } else {
    w.chunk_start = std::min(w.chunk_start, log_time_ns);
    w.chunk_end = std::max(w.chunk_end, log_time_ns);
  }
  ++w.chunk_messages;
  if (w.message_count == 0) {
    w.start_time = w.end_time = log_time_ns;
  } else {
    w.start_time = std::min(w.start_time, log_time_ns);
    w.end_time = std::max(w.end_time, log_time_ns);
  }
  ++w.message_count;

  if (w.chunk.size() >= w.options.chunk_size) return w.CloseChunk();
  return Status::Ok();
}

Status McapWriter::Impl::CloseChunk() {
  if (chunk.empty()) return Status::Ok();
  const uint32_t records_crc = Crc32(0, chunk);
  std::span<const uint8_t> stored = chunk;
  if (compressor != nullptr) {
    auto compressed = compressor->Compress(chunk);
    if (!compressed.ok()) {
      state = State::kFailed;
      failure = compressed.error();
      return failure;
    }
    stored = compressed.value();
  }
  const std::string_view compression = CompressionName(options.compression);

  ChunkIndexEntry entry;
  entry.start_time = chunk_start;
  entry.end_time = chunk_end;
  entry.offset = offset;
  entry.compressed_size = stored.size();
  entry.uncompressed_size = chunk.size();

  scratch.clear();
  PutU8(scratch, kOpChunk);
  PutU64(scratch, 8 + 8 + 8 + 4 + 4 + compression.size() + 8 + stored.size());
  PutU64(scratch, chunk_start);
  PutU64(scratch, chunk_end);
  PutU64(scratch, chunk.size());
  PutU32(scratch, records_crc);
  PutString(scratch, compression);
  PutU64(scratch, stored.size());
  if (Status s = Emit(scratch, "Chunk record"); !s.ok()) return s;
  if (Status s = Emit(stored, "Chunk record"); !s.ok()) return s;
  entry.length = offset - entry.offset;

  // One Message Index record per channel in the chunk, entries in log-time order.
  scratch.clear();
  entry.index_offsets_begin = index_offsets.size();
  const uint64_t index_start = offset;
  for (uint16_t id : chunk_channels) {
    ChannelState& ch = channels[id - 1];
    if (!ch.sorted) {
      std::sort(ch.index.begin(), ch.index.end(), [](const IndexEntry& a, const IndexEntry& b) {
        return a.log_time != b.log_time ? a.log_time < b.log_time : a.offset < b.offset;
      });
    }
    index_offsets.emplace_back(id, index_start + scratch.size());
    PutU8(scratch, kOpMessageIndex);
    PutU64(scratch, 2 + 4 + 16 * ch.index.size());
    PutU16(scratch, id);
    PutU32(scratch, static_cast<uint32_t>(16 * ch.index.size()));
    for (const IndexEntry& e : ch.index) {
      PutU64(scratch, e.log_time);
      PutU64(scratch, e.offset);
    }
    ch.index.clear();
  }
  entry.index_offsets_end = index_offsets.size();
  if (Status s = Emit(scratch, "Message Index records"); !s.ok()) return s;
  entry.index_length = offset - index_start;
  chunk_indexes.push_back(entry);

  chunk.clear();
  chunk_channels.clear();
  chunk_messages = 0;
  if (Status s = sink->Flush(); !s.ok()) {
    return Fail(Format("flushing after the chunk at offset %llu", ull(entry.offset)), s);
  }
  return Status::Ok();
}

Status McapWriter::FlushChunk() {
  if (Status s = impl_->Usable(); !s.ok()) return s;
  return impl_->CloseChunk();
}

Status McapWriter::Close() {
  Impl& w = *impl_;
  if (Status s = w.Usable(); !s.ok()) return s;
  if (Status s = w.CloseChunk(); !s.ok()) return s;

  // Data End: the CRC of every byte before it.
  w.scratch.clear();
  PutU8(w.scratch, kOpDataEnd);
  PutU64(w.scratch, 4);
  PutU32(w.scratch, w.crc);
  if (Status s = w.Emit(w.scratch, "Data End record"); !s.ok()) return s;

  // The summary, grouped by opcode; each group gets a Summary Offset record.
  w.crc = 0;
  const uint64_t summary_start = w.offset;
  struct Group {
    uint8_t op;
    uint64_t start, length;
  };
  Group groups[4];
  int n_groups = 0;
  auto emit_group = [&](uint8_t op, std::span<const uint8_t> bytes) -> Status {
    if (bytes.empty()) return Status::Ok();
    groups[n_groups++] = {op, w.offset, bytes.size()};
    return w.Emit(bytes, "summary");
  };
  if (Status s = emit_group(kOpSchema, w.schema_records); !s.ok()) return s;
  if (Status s = emit_group(kOpChannel, w.channel_records); !s.ok()) return s;

  w.scratch.clear();
  size_t at = BeginRecord(w.scratch, kOpStatistics);
  PutU64(w.scratch, w.message_count);
  PutU16(w.scratch, w.schema_count);
  PutU32(w.scratch, static_cast<uint32_t>(w.channels.size()));
  PutU32(w.scratch, 0);  // attachments
  PutU32(w.scratch, 0);  // metadata
  PutU32(w.scratch, static_cast<uint32_t>(w.chunk_indexes.size()));
  PutU64(w.scratch, w.start_time);
  PutU64(w.scratch, w.end_time);
  PutU32(w.scratch, static_cast<uint32_t>(w.channels.size() * 10));
  for (size_t i = 0; i < w.channels.size(); ++i) {
    PutU16(w.scratch, static_cast<uint16_t>(i + 1));
    PutU64(w.scratch, w.channels[i].message_count);
  }
  EndRecord(w.scratch, at);
  if (Status s = emit_group(kOpStatistics, w.scratch); !s.ok()) return s;

  w.scratch.clear();
  for (const ChunkIndexEntry& c : w.chunk_indexes) {
    at = BeginRecord(w.scratch, kOpChunkIndex);
    PutU64(w.scratch, c.start_time);
    PutU64(w.scratch, c.end_time);
    PutU64(w.scratch, c.offset);
    PutU64(w.scratch, c.length);
    PutU32(w.scratch, static_cast<uint32_t>(10 * (c.index_offsets_end - c.index_offsets_begin)));
    for (size_t i = c.index_offsets_begin; i < c.index_offsets_end; ++i) {
      PutU16(w.scratch, w.index_offsets[i].first);
      PutU64(w.scratch, w.index_offsets[i].second);
    }
    PutU64(w.scratch, c.index_length);
    PutString(w.scratch, CompressionName(w.options.compression));
    PutU64(w.scratch, c.compressed_size);
    PutU64(w.scratch, c.uncompressed_size);
    EndRecord(w.scratch, at);
  }
  if (Status s = emit_group(kOpChunkIndex, w.scratch); !s.ok()) return s;

  const uint64_t summary_offset_start = w.offset;
  w.scratch.clear();
  for (int i = 0; i < n_groups; ++i) {
    PutU8(w.scratch, kOpSummaryOffset);
    PutU64(w.scratch, 1 + 8 + 8);
    PutU8(w.scratch, groups[i].op);
    PutU64(w.scratch, groups[i].start);
    PutU64(w.scratch, groups[i].length);
  }
  // The footer's CRC covers the summary, the summary offsets and the footer up to itself.
  PutU8(w.scratch, kOpFooter);
  PutU64(w.scratch, kFooterContent);
  PutU64(w.scratch, summary_start);
  PutU64(w.scratch, summary_offset_start);
  PutU32(w.scratch, Crc32(w.crc, w.scratch));
  PutBytes(w.scratch, kMagic);
  if (Status s = w.Emit(w.scratch, "summary offsets and Footer"); !s.ok()) return s;

  if (Status s = w.sink->Flush(); !s.ok()) return w.Fail("flushing the finished file", s);
  w.state = Impl::State::kClosed;
  return Status::Ok();
}

}  // namespace rheo::record
