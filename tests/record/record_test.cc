// rheo_record: MCAP files written and read back with each compression, many chunks, an empty file,
// files cut at many points, corrupted bytes, a kill -9 during a recording, and sinks that fail.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "record/mcap.h"
#include "record/mcap_format.h"

namespace rheo::record {
namespace {

struct Sent {
  uint16_t channel;
  uint32_t sequence;
  uint64_t log_time, publish_time;
  std::vector<uint8_t> data;
};

struct Got {
  std::string topic;
  std::string schema;  // "" without one
  uint32_t sequence;
  uint64_t log_time, publish_time;
  std::vector<uint8_t> data;
  uint64_t chunk_offset;
};

std::vector<uint8_t> Payload(size_t n, uint32_t seed) {
  std::vector<uint8_t> v(n);
  uint32_t x = seed * 2654435761u + 1;
  for (size_t i = 0; i < n; ++i) {
    x = x * 1664525u + 1013904223u;
    v[i] = static_cast<uint8_t>((i % 7 == 0) ? (x >> 24) : (i & 0x3f));  // partly compressible
  }
  return v;
}

std::span<const uint8_t> Bytes(std::string_view s) {
  return {reinterpret_cast<const uint8_t*>(s.data()), s.size()};
}

Result<std::vector<Got>> ReadAll(McapReader& reader) {
  std::vector<Got> out;
  Status s = reader.ForEachMessage([&](const Message& m) {
    out.push_back({m.channel->topic, m.schema ? m.schema->name : "", m.sequence, m.log_time,
                   m.publish_time, std::vector<uint8_t>(m.data.begin(), m.data.end()),
                   m.chunk_offset});
    return Status::Ok();
  });
  if (!s.ok()) return s.error();
  return out;
}

std::string Describe(const Status& s) {
  return s.ok() ? "ok" : s.error().message;
}
template <typename T>
std::string Describe(const Result<T>& r) {
  return r.ok() ? "ok" : r.error().message;
}

/// A sink that accepts `limit` bytes, then fails as a full disk would (the last write partly).
class FullDiskSink final : public ByteSink {
 public:
  explicit FullDiskSink(size_t limit) : limit_(limit) {}
  Status Write(std::span<const uint8_t> b) override {
    const size_t room = limit_ - bytes_.size();
    bytes_.insert(bytes_.end(), b.begin(), b.begin() + std::min(room, b.size()));
    if (b.size() > room) {
      ++failures_;
      return ResourceExhausted("test sink: no space left on device (full at " +
                               std::to_string(limit_) + " bytes)");
    }
    return Status::Ok();
  }
  Status Flush() override { return Status::Ok(); }
  const std::vector<uint8_t>& bytes() const { return bytes_; }
  int failures() const { return failures_; }

 private:
  size_t limit_;
  std::vector<uint8_t> bytes_;
  int failures_ = 0;
};

/// Three channels: /pose (1 kHz, small), /frame (large, every 17th), /log (no schema, log times
/// running up to 5 ms behind the others, so chunks overlap in time), plus ties in log time.
std::vector<Sent> SampleMessages(int n) {
  std::vector<Sent> out;
  for (int i = 0; i < n; ++i) {
    const uint64_t t = 1'700'000'000'000'000'000ull + uint64_t(i) * 1'000'000;
    out.push_back({1, uint32_t(i), t, t + 10, Payload(40 + i % 160, i)});
    if (i % 17 == 0) out.push_back({2, uint32_t(i / 17), t, t, Payload(3000, 10000 + i)});
    if (i % 5 == 0) {
      const uint64_t late = t - uint64_t((i * 7919) % 5) * 1'000'000;
      out.push_back({3, uint32_t(i / 5), late, late, Payload(20, 20000 + i)});
    }
  }
  return out;
}

struct Recording {
  std::vector<uint8_t> bytes;
  std::vector<Sent> sent;
  uint32_t chunks = 0;
};

Recording Record(const WriterOptions& options, int n) {
  Recording rec;
  MemorySink sink;
  McapWriter w;
  EXPECT_TRUE(w.Open(sink, "", "rheo record_test", options).ok());
  auto pose = w.AddSchema("rheo.test.Pose", "protobuf", Bytes("descriptor bytes"));
  auto raw = w.AddSchema("raw", "", {});
  EXPECT_TRUE(pose.ok() && raw.ok());
  EXPECT_EQ(*pose, 1);
  auto c1 = w.AddChannel(*pose, "/pose", "protobuf", {{"rate_hz", "1000"}});
  auto c2 = w.AddChannel(*pose, "/frame", "protobuf");
  auto c3 = w.AddChannel(0, "/log", "json", {{"a", "1"}, {"b", ""}});
  EXPECT_TRUE(c1.ok() && c2.ok() && c3.ok());
  EXPECT_EQ(*c3, 3);
  rec.sent = SampleMessages(n);
  for (const Sent& m : rec.sent) {
    Status s = w.Write(m.channel, m.sequence, m.log_time, m.publish_time, m.data);
    EXPECT_TRUE(s.ok()) << Describe(s);
  }
  rec.chunks = w.chunk_count();
  Status closed = w.Close();
  EXPECT_TRUE(closed.ok()) << Describe(closed);
  rec.chunks = w.chunk_count();
  EXPECT_EQ(w.bytes_written(), sink.bytes().size());
  rec.bytes = sink.Take();
  return rec;
}

const char* kTopics[] = {"", "/pose", "/frame", "/log"};

/// What a reader must return: the messages stably sorted by log time.
std::vector<Sent> InLogTimeOrder(std::vector<Sent> sent) {
  std::stable_sort(sent.begin(), sent.end(),
                   [](const Sent& a, const Sent& b) { return a.log_time < b.log_time; });
  return sent;
}

void ExpectSame(const std::vector<Sent>& expected, const std::vector<Got>& got) {
  ASSERT_EQ(expected.size(), got.size());
  for (size_t i = 0; i < got.size(); ++i) {
    const Sent& e = expected[i];
    const Got& g = got[i];
    ASSERT_EQ(g.topic, kTopics[e.channel]) << "message " << i;
    ASSERT_EQ(g.sequence, e.sequence) << "message " << i;
    ASSERT_EQ(g.log_time, e.log_time) << "message " << i;
    ASSERT_EQ(g.publish_time, e.publish_time) << "message " << i;
    ASSERT_EQ(g.data, e.data) << "message " << i;
    ASSERT_EQ(g.schema, e.channel == 3 ? "" : "rheo.test.Pose");
  }
}

class RoundTrip : public testing::TestWithParam<Compression> {};

TEST_P(RoundTrip, EveryMessageBackInLogTimeOrder) {
  WriterOptions options;
  options.compression = GetParam();
  options.chunk_size = 8192;
  const Recording rec = Record(options, 600);
  ASSERT_GT(rec.chunks, 10u);

  auto opened = McapReader::OpenView(rec.bytes, "roundtrip.mcap");
  ASSERT_TRUE(opened.ok()) << Describe(opened);
  McapReader& r = *opened;
  EXPECT_FALSE(r.truncation().has_value());
  EXPECT_TRUE(r.has_summary());
  EXPECT_EQ(r.header().library, "rheo record_test");
  EXPECT_EQ(r.header().profile, "");
  ASSERT_EQ(r.schemas().size(), 2u);
  EXPECT_EQ(r.schemas().at(1).encoding, "protobuf");
  EXPECT_EQ(r.schemas().at(1).data, std::vector<uint8_t>(Bytes("descriptor bytes").begin(),
                                                         Bytes("descriptor bytes").end()));
  EXPECT_EQ(r.schemas().at(2).encoding, "");
  ASSERT_EQ(r.channels().size(), 3u);
  EXPECT_EQ(r.channels().at(1).metadata.at("rate_hz"), "1000");
  EXPECT_EQ(r.channels().at(3).metadata.size(), 2u);
  EXPECT_EQ(r.channels().at(3).schema_id, 0);
  EXPECT_EQ(r.channels().at(2).message_encoding, "protobuf");

  ASSERT_EQ(r.chunks().size(), rec.chunks);
  for (const ChunkInfo& c : r.chunks()) {
    EXPECT_EQ(c.compression, GetParam());
    EXPECT_NE(c.uncompressed_crc, 0u);
    if (GetParam() != Compression::kNone) {
      EXPECT_LT(c.compressed_size, c.uncompressed_size);
    }
  }

  ASSERT_TRUE(r.statistics().has_value());
  const Statistics& st = *r.statistics();
  EXPECT_EQ(st.message_count, rec.sent.size());
  EXPECT_EQ(st.chunk_count, rec.chunks);
  EXPECT_EQ(st.schema_count, 2);
  EXPECT_EQ(st.channel_count, 3u);
  EXPECT_EQ(st.channel_message_counts.at(1), 600u);
  EXPECT_EQ(st.channel_message_counts.at(2), 36u);  // i = 0, 17, ..., 595
  EXPECT_EQ(st.channel_message_counts.at(3), 120u);
  uint64_t lo = UINT64_MAX, hi = 0;
  for (const Sent& m : rec.sent) lo = std::min(lo, m.log_time), hi = std::max(hi, m.log_time);
  EXPECT_EQ(st.message_start_time, lo);
  EXPECT_EQ(st.message_end_time, hi);

  auto got = ReadAll(r);
  ASSERT_TRUE(got.ok()) << Describe(got);
  ExpectSame(InLogTimeOrder(rec.sent), *got);

  // A second cursor over the same reader sees the same messages.
  auto again = ReadAll(r);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->size(), got->size());
}

INSTANTIATE_TEST_SUITE_P(Compressions, RoundTrip,
                         testing::Values(Compression::kNone, Compression::kZstd, Compression::kLz4),
                         [](const auto& info) {
                           const std::string_view n = CompressionName(info.param);
                           return n.empty() ? std::string("none") : std::string(n);
                         });

TEST(Record, ManyChunksOneMessageEach) {
  WriterOptions options;
  options.compression = Compression::kZstd;
  options.chunk_size = 1;  // every message closes its chunk
  const Recording rec = Record(options, 400);
  EXPECT_EQ(rec.chunks, rec.sent.size());
  auto r = McapReader::OpenView(rec.bytes);
  ASSERT_TRUE(r.ok()) << Describe(r);
  EXPECT_EQ(r->chunks().size(), rec.sent.size());
  auto got = ReadAll(*r);
  ASSERT_TRUE(got.ok()) << Describe(got);
  ExpectSame(InLogTimeOrder(rec.sent), *got);
  std::set<uint64_t> offsets;
  for (const Got& g : *got) offsets.insert(g.chunk_offset);
  EXPECT_EQ(offsets.size(), rec.sent.size());
}

TEST(Record, EmptyFile) {
  for (bool with_channel : {false, true}) {
    MemorySink sink;
    McapWriter w;
    ASSERT_TRUE(w.Open(sink, "ros2", "empty").ok());
    if (with_channel) {
      ASSERT_TRUE(w.AddChannel(0, "/nothing", "json").ok());
    }
    ASSERT_TRUE(w.Close().ok());
    auto r = McapReader::OpenView(sink.bytes());
    ASSERT_TRUE(r.ok()) << Describe(r);
    EXPECT_FALSE(r->truncation());
    EXPECT_EQ(r->header().profile, "ros2");
    EXPECT_EQ(r->chunks().size(), 0u);
    EXPECT_EQ(r->channels().size(), with_channel ? 1u : 0u);
    ASSERT_TRUE(r->statistics());
    EXPECT_EQ(r->statistics()->message_count, 0u);
    EXPECT_EQ(r->statistics()->message_start_time, 0u);
    auto got = ReadAll(*r);
    ASSERT_TRUE(got.ok()) << Describe(got);
    EXPECT_TRUE(got->empty());
  }
}

class Truncated : public testing::TestWithParam<Compression> {};

// Every cut keeps exactly the messages of the chunks that end before it, and never fails after
// the magic (nor crashes anywhere: ASan runs this too).
TEST_P(Truncated, EveryCompleteChunkRecovered) {
  WriterOptions options;
  options.compression = GetParam();
  options.chunk_size = 1500;
  const Recording rec = Record(options, 150);
  const uint64_t size = rec.bytes.size();
  auto full = McapReader::OpenView(rec.bytes);
  ASSERT_TRUE(full.ok());
  auto all = ReadAll(*full);
  ASSERT_TRUE(all.ok());
  const std::vector<ChunkInfo> chunks = full->chunks();
  ASSERT_GT(chunks.size(), 8u);

  std::set<uint64_t> cuts;
  for (uint64_t c = 0; c <= size; c += 11) cuts.insert(c);
  for (uint64_t c = 0; c < 80; ++c) cuts.insert(c);
  for (uint64_t c = size - std::min<uint64_t>(size, 200); c <= size; ++c) cuts.insert(c);
  for (const ChunkInfo& c : chunks) {
    for (int64_t d : {-9, -1, 0, 1, 8, 9, 10, 40}) {
      cuts.insert(c.offset + d);
      cuts.insert(c.offset + c.length + d);
    }
    cuts.insert(c.offset + c.length / 2);
  }
  for (uint64_t cut : cuts) {
    if (cut > size) continue;
    auto r = McapReader::OpenView(std::span<const uint8_t>(rec.bytes).first(cut), "cut.mcap");
    if (cut < 8) {
      EXPECT_FALSE(r.ok()) << "cut " << cut;
      continue;
    }
    ASSERT_TRUE(r.ok()) << "cut " << cut << ": " << Describe(r);
    if (cut == size) {
      EXPECT_FALSE(r->truncation());
    } else {
      ASSERT_TRUE(r->truncation()) << "cut " << cut;
      EXPECT_LE(r->truncation()->valid_bytes, cut);
      EXPECT_FALSE(r->truncation()->reason.empty());
    }
    std::multiset<std::pair<std::string, uint32_t>> expected;
    for (const Got& g : *all) {
      for (const ChunkInfo& c : chunks) {
        if (c.offset == g.chunk_offset && c.offset + c.length <= cut) {
          expected.insert({g.topic, g.sequence});
        }
      }
    }
    auto got = ReadAll(*r);
    ASSERT_TRUE(got.ok()) << "cut " << cut << ": " << Describe(got);
    std::multiset<std::pair<std::string, uint32_t>> seen;
    uint64_t last = 0;
    for (const Got& g : *got) {
      seen.insert({g.topic, g.sequence});
      EXPECT_GE(g.log_time, last);
      last = g.log_time;
    }
    ASSERT_EQ(seen, expected) << "cut " << cut;
  }
}

INSTANTIATE_TEST_SUITE_P(Compressions, Truncated,
                         testing::Values(Compression::kNone, Compression::kZstd, Compression::kLz4),
                         [](const auto& info) {
                           const std::string_view n = CompressionName(info.param);
                           return n.empty() ? std::string("none") : std::string(n);
                         });

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          (name + "-" + std::to_string(::getpid()) + ".mcap"))
      .string();
}

std::string OffsetText(uint64_t offset) {
  return "offset " + std::to_string(offset);
}

TEST(Record, CorruptedChunkIsACrcErrorNamingTheChunk) {
  WriterOptions options;
  options.compression = Compression::kNone;
  options.chunk_size = 4096;
  Recording rec = Record(options, 200);
  auto clean = McapReader::OpenView(rec.bytes);
  ASSERT_TRUE(clean.ok());
  const ChunkInfo chunk = clean->chunks().at(3);
  rec.bytes[chunk.offset + chunk.length - 5] ^= 0x40;  // inside the chunk's last message

  // Closed file: Open sees the data section CRC fail and names the chunk.
  auto r = McapReader::OpenView(rec.bytes, "bad.mcap");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kDataLoss);
  EXPECT_NE(r.error().message.find("CRC mismatch"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find(OffsetText(chunk.offset)), std::string::npos)
      << r.error().message;
  EXPECT_EQ(r.error().message.rfind("bad.mcap: ", 0), 0u) << r.error().message;

  // The same file cut after its last chunk (no Data End CRC to check): reading reaches the chunk.
  const ChunkInfo last = clean->chunks().back();
  auto cut =
      McapReader::OpenView(std::span<const uint8_t>(rec.bytes).first(last.offset + last.length));
  ASSERT_TRUE(cut.ok()) << Describe(cut);
  ASSERT_TRUE(cut->truncation());
  auto got = ReadAll(*cut);
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.error().code, ErrorCode::kDataLoss);
  EXPECT_NE(got.error().message.find("CRC mismatch"), std::string::npos) << got.error().message;
  EXPECT_NE(got.error().message.find(OffsetText(chunk.offset)), std::string::npos);
}

TEST(Record, CorruptedCompressedChunkNamesTheChunk) {
  for (Compression c : {Compression::kZstd, Compression::kLz4}) {
    WriterOptions options;
    options.compression = c;
    options.chunk_size = 4096;
    Recording rec = Record(options, 200);
    auto clean = McapReader::OpenView(rec.bytes);
    ASSERT_TRUE(clean.ok());
    const ChunkInfo chunk = clean->chunks().at(2);
    rec.bytes[chunk.offset + chunk.length - chunk.compressed_size / 2] ^= 0x01;
    auto r = McapReader::OpenView(rec.bytes);
    const Error e = r.ok() ? ReadAll(*r).error() : r.error();
    EXPECT_EQ(e.code, ErrorCode::kDataLoss);
    EXPECT_NE(e.message.find(OffsetText(chunk.offset)), std::string::npos) << e.message;
  }
}

TEST(Record, CorruptedSummaryIsACrcError) {
  Recording rec = Record(WriterOptions{}, 50);
  rec.bytes[rec.bytes.size() - 60] ^= 0x10;  // in the summary offsets
  auto r = McapReader::OpenView(rec.bytes);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("summary CRC mismatch"), std::string::npos) << r.error().message;
}

TEST(Record, NotAnMcapFile) {
  const std::string text = "this is a text file, long enough to hold a footer and more bytes...";
  auto r = McapReader::OpenView(Bytes(text), "notes.txt");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message.find("notes.txt"), std::string::npos);
  const std::string empty_path = TempPath("rheo-record-empty");
  { std::ofstream touch(empty_path); }
  auto empty = McapReader::OpenFile(empty_path);
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.error().code, ErrorCode::kDataLoss);
  EXPECT_NE(empty.error().message.find("empty"), std::string::npos) << empty.error().message;
  std::remove(empty_path.c_str());
  auto missing = McapReader::OpenFile("/nonexistent-rheo-dir/none.mcap");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("/nonexistent-rheo-dir/none.mcap"), std::string::npos);
}

TEST(Record, WriterRefusesMisuse) {
  MemorySink sink;
  McapWriter w;
  const uint8_t one[1] = {1};
  EXPECT_EQ(w.Write(1, 0, 0, 0, one).error().code, ErrorCode::kFailedPrecondition);
  WriterOptions bad;
  bad.chunk_size = 0;
  EXPECT_EQ(w.Open(sink, "", "t", bad).error().code, ErrorCode::kInvalidArgument);
  bad.chunk_size = 1024;
  bad.zstd_level = 99;
  EXPECT_EQ(w.Open(sink, "", "t", bad).error().code, ErrorCode::kInvalidArgument);
  ASSERT_TRUE(w.Open(sink, "", "t").ok());
  EXPECT_EQ(w.Open(sink, "", "t").error().code, ErrorCode::kFailedPrecondition);
  EXPECT_EQ(w.AddChannel(4, "/x", "json").error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(w.AddChannel(0, "", "json").error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(w.AddSchema("", "protobuf", one).error().code, ErrorCode::kInvalidArgument);
  const Status unknown = w.Write(9, 0, 0, 0, one);
  EXPECT_EQ(unknown.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(unknown.error().message.find("channel 9"), std::string::npos);
  ASSERT_TRUE(w.AddChannel(0, "/x", "json").ok());
  ASSERT_TRUE(w.Write(1, 0, 5, 5, one).ok());
  ASSERT_TRUE(w.Close().ok());
  EXPECT_EQ(w.Write(1, 0, 0, 0, one).error().code, ErrorCode::kFailedPrecondition);
  EXPECT_EQ(w.Close().error().code, ErrorCode::kFailedPrecondition);
}

TEST(Record, FileSinkErrorsNameTheFile) {
  auto missing = FileSink::Create("/nonexistent-rheo-dir/session.mcap");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("/nonexistent-rheo-dir/session.mcap"), std::string::npos);

  auto dir = FileSink::Create("/tmp");
  ASSERT_FALSE(dir.ok());
  EXPECT_NE(dir.error().message.find("/tmp"), std::string::npos);

  auto not_dir = FileSink::Create("/dev/null/session.mcap");
  ASSERT_FALSE(not_dir.ok());
  EXPECT_NE(not_dir.error().message.find("/dev/null/session.mcap"), std::string::npos);

  // /dev/full fails every write with ENOSPC, as a full disk does.
  if (::access("/dev/full", W_OK) != 0) GTEST_SKIP() << "no /dev/full";
  auto full = FileSink::Create("/dev/full");
  ASSERT_TRUE(full.ok()) << Describe(full);
  McapWriter w;
  const Status s = w.Open(**full, "", "t");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(s.error().message.find("/dev/full"), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("free"), std::string::npos) << s.error().message;
  EXPECT_EQ(w.Close().error().code, ErrorCode::kResourceExhausted);
}

TEST(Record, DiskFullMidRecordingStopsCleanly) {
  FullDiskSink sink(20000);
  McapWriter w;
  WriterOptions options;
  options.chunk_size = 700;
  options.compression = Compression::kLz4;
  ASSERT_TRUE(w.Open(sink, "", "t", options).ok());
  auto ch = w.AddChannel(0, "/pose", "json");
  ASSERT_TRUE(ch.ok());
  Status failed;
  int written = 0;
  for (int i = 0; i < 10000 && failed.ok(); ++i) {
    failed = w.Write(*ch, i, i, i, Payload(100, i));
    if (failed.ok()) ++written;
  }
  ASSERT_FALSE(failed.ok()) << "the sink never filled";
  EXPECT_EQ(failed.error().code, ErrorCode::kResourceExhausted);
  EXPECT_NE(failed.error().message.find("no space left"), std::string::npos);
  EXPECT_NE(failed.error().message.find("offset"), std::string::npos) << failed.error().message;
  // Every later call repeats the error without touching the sink again.
  EXPECT_EQ(w.Write(*ch, 0, 0, 0, Payload(10, 0)).error().message, failed.error().message);
  EXPECT_EQ(w.AddChannel(0, "/more", "json").error().message, failed.error().message);
  EXPECT_EQ(w.FlushChunk().error().message, failed.error().message);
  EXPECT_EQ(w.Close().error().message, failed.error().message);
  EXPECT_EQ(sink.failures(), 1);

  // What reached the disk reads as a truncated file holding the complete chunks.
  auto r = McapReader::OpenView(sink.bytes());
  ASSERT_TRUE(r.ok()) << Describe(r);
  ASSERT_TRUE(r->truncation());
  auto got = ReadAll(*r);
  ASSERT_TRUE(got.ok()) << Describe(got);
  EXPECT_GT(got->size(), 10u);
  EXPECT_LE(got->size(), static_cast<size_t>(written));
  for (size_t i = 0; i < got->size(); ++i) EXPECT_EQ((*got)[i].sequence, i);
}

TEST(Record, FileSinkRoundTripAndUnclosedFile) {
  const std::string path = TempPath("rheo-record-file");
  {
    auto sink = FileSink::Create(path);
    ASSERT_TRUE(sink.ok()) << Describe(sink);
    McapWriter w;
    WriterOptions options;
    options.chunk_size = 2048;
    ASSERT_TRUE(w.Open(**sink, "", "t", options).ok());
    auto ch = w.AddChannel(0, "/pose", "json");
    for (int i = 0; i < 100; ++i) ASSERT_TRUE(w.Write(*ch, i, i, i, Payload(50, i)).ok());
    ASSERT_TRUE(w.Close().ok());
    ASSERT_TRUE((*sink)->Close().ok());
    EXPECT_EQ((*sink)->bytes_written(), w.bytes_written());
  }
  {
    auto r = McapReader::OpenFile(path);
    ASSERT_TRUE(r.ok()) << Describe(r);
    EXPECT_FALSE(r->truncation());
    auto got = ReadAll(*r);
    ASSERT_TRUE(got.ok());
    EXPECT_EQ(got->size(), 100u);
  }
  // A writer destroyed without Close leaves its flushed chunks; the open one is lost.
  {
    auto sink = FileSink::Create(path);
    ASSERT_TRUE(sink.ok());
    McapWriter w;
    ASSERT_TRUE(w.Open(**sink, "", "t").ok());
    auto ch = w.AddChannel(0, "/pose", "json");
    for (int i = 0; i < 30; ++i) ASSERT_TRUE(w.Write(*ch, i, i, i, Payload(50, i)).ok());
    ASSERT_TRUE(w.FlushChunk().ok());
    for (int i = 30; i < 33; ++i) ASSERT_TRUE(w.Write(*ch, i, i, i, Payload(50, i)).ok());
  }
  {
    auto r = McapReader::OpenFile(path);
    ASSERT_TRUE(r.ok()) << Describe(r);
    ASSERT_TRUE(r->truncation());
    EXPECT_NE(r->truncation()->reason.find("not closed"), std::string::npos)
        << r->truncation()->reason;
    auto got = ReadAll(*r);
    ASSERT_TRUE(got.ok());
    EXPECT_EQ(got->size(), 30u);
  }
  std::remove(path.c_str());
}

// A recorder killed with SIGKILL leaves every chunk it had finished readable.
TEST(Record, KilledRecorderLeavesEveryCompleteChunk) {
  const std::string path = TempPath("rheo-record-kill");
  int report[2];
  ASSERT_EQ(::pipe(report), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(report[0]);
    auto sink = FileSink::Create(path);
    if (!sink.ok()) ::_exit(2);
    McapWriter w;
    WriterOptions options;
    options.chunk_size = 3000;
    if (!w.Open(**sink, "", "t", options).ok()) ::_exit(3);
    auto ch = w.AddChannel(0, "/pose", "json");
    uint32_t chunks = 0;
    for (uint32_t i = 0;; ++i) {
      if (!w.Write(*ch, i, i, i, Payload(200, i)).ok()) ::_exit(4);
      if (w.chunk_count() != chunks) {
        chunks = w.chunk_count();
        const uint64_t complete = w.message_count();  // the chunk just closed holds them all
        if (::write(report[1], &complete, sizeof complete) != sizeof complete) ::_exit(5);
        if (chunks == 6) {
          // Half a chunk more that never reaches the file, then wait to be killed.
          for (uint32_t j = 1; j < 5; ++j) (void)w.Write(*ch, i + j, i + j, i + j, Payload(200, j));
          for (;;) ::pause();
        }
      }
    }
  }
  ::close(report[1]);
  uint64_t complete = 0;
  for (int i = 0; i < 6; ++i) {
    ASSERT_EQ(::read(report[0], &complete, sizeof complete), ssize_t(sizeof complete));
  }
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
  ::close(report[0]);

  auto r = McapReader::OpenFile(path);
  ASSERT_TRUE(r.ok()) << Describe(r);
  ASSERT_TRUE(r->truncation());
  EXPECT_EQ(r->chunks().size(), 6u);
  auto got = ReadAll(*r);
  ASSERT_TRUE(got.ok()) << Describe(got);
  EXPECT_EQ(got->size(), complete);
  std::remove(path.c_str());
}

// Files from other writers: messages outside chunks, a channel defined only inside a chunk that
// comes later in the file than a chunk using it, and no summary.
TEST(Record, ForeignLayoutsRead) {
  using namespace internal;
  auto record = [](std::vector<uint8_t>& f, uint8_t op, const std::vector<uint8_t>& content) {
    PutU8(f, op);
    PutU64(f, content.size());
    PutBytes(f, content);
  };
  auto channel = [](uint16_t id, const std::string& topic) {
    std::vector<uint8_t> c;
    PutU16(c, id);
    PutU16(c, 0);
    PutString(c, topic);
    PutString(c, "json");
    PutU32(c, 0);
    return c;
  };
  auto message = [](uint16_t ch, uint32_t seq, uint64_t t) {
    std::vector<uint8_t> c;
    PutU16(c, ch);
    PutU32(c, seq);
    PutU64(c, t);
    PutU64(c, t);
    PutString(c, "{}");
    return c;
  };
  auto chunk = [&](const std::vector<uint8_t>& records, uint64_t t0, uint64_t t1) {
    std::vector<uint8_t> c;
    PutU64(c, t0);
    PutU64(c, t1);
    PutU64(c, records.size());
    PutU32(c, 0);  // no CRC
    PutString(c, "");
    PutU64(c, records.size());
    PutBytes(c, records);
    return c;
  };
  std::vector<uint8_t> f(kMagic, kMagic + 8);
  std::vector<uint8_t> header;
  PutString(header, "");
  PutString(header, "hand-made");
  record(f, kOpHeader, header);
  record(f, kOpChannel, channel(1, "/a"));
  record(f, kOpMessage, message(1, 0, 300));
  record(f, kOpMessage, message(1, 1, 100));
  std::vector<uint8_t> in_chunk2;
  record(in_chunk2, kOpMessage, message(2, 0, 150));  // channel 2 is defined in a later chunk
  record(f, kOpChunk, chunk(in_chunk2, 150, 150));
  std::vector<uint8_t> in_chunk3;
  record(in_chunk3, kOpChannel, channel(2, "/b"));
  record(in_chunk3, kOpMessage, message(2, 1, 400));
  record(f, kOpChunk, chunk(in_chunk3, 400, 400));
  const size_t last_loose = f.size();
  record(f, kOpMessage, message(1, 2, 200));
  std::vector<uint8_t> data_end;
  PutU32(data_end, 0);
  record(f, kOpDataEnd, data_end);
  std::vector<uint8_t> footer;
  PutU64(footer, 0);
  PutU64(footer, 0);
  PutU32(footer, 0);
  record(f, kOpFooter, footer);
  PutBytes(f, kMagic);

  auto r = McapReader::OpenView(f);
  ASSERT_TRUE(r.ok()) << Describe(r);
  EXPECT_FALSE(r->truncation());
  EXPECT_FALSE(r->has_summary());
  auto got = ReadAll(*r);
  ASSERT_TRUE(got.ok()) << Describe(got);
  std::vector<std::pair<std::string, uint64_t>> seen;
  for (const Got& g : *got) seen.emplace_back(g.topic, g.log_time);
  const std::vector<std::pair<std::string, uint64_t>> want = {
      {"/a", 100}, {"/b", 150}, {"/a", 200}, {"/a", 300}, {"/b", 400}};
  EXPECT_EQ(seen, want);

  // A message on a channel nothing defines is an error, not a crash.
  f[last_loose + kRecordPrefix] = 7;  // the channel id of the last loose message
  auto bad = McapReader::OpenView(f);
  ASSERT_TRUE(bad.ok()) << Describe(bad);
  auto none = ReadAll(*bad);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("channel 7"), std::string::npos) << none.error().message;
}

}  // namespace
}  // namespace rheo::record
