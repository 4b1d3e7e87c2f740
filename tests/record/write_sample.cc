// write_sample: records a synthetic haptic session (1 kHz ToolSample, 60 Hz ~100 kB Frame, both
// protobuf with their FileDescriptorSet embedded as the schema) through FileSink, for the Node
// reader check (read_mcap.mjs) and for measuring the writer's throughput.
//
//   write_sample --out FILE [--compression zstd|lz4|none] [--seconds 2] [--chunk-size BYTES]
//                [--zstd-level N] [--truncate] [--verify] [--report FILE.json]
//
// --truncate cuts the finished file a third of the way into its middle chunk, as a crash would,
// and the report's expected_per_topic then counts only the messages of the chunks before the cut
// (from the writer's own bookkeeping, not from a reader). --verify then reads the file back with
// McapReader, parses every payload with the generated classes and checks the counts and each
// message's sequence and stamp, timing the read. The report is JSON on stdout, and in --report FILE
// when given.
#include <google/protobuf/descriptor.pb.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "record/mcap.h"
#include "sample.pb.h"

namespace {

using rheo::record::Compression;
using rheo::record::McapWriter;
namespace sample = rheo::record::sample;

/// The FileDescriptorSet of `d`'s file and everything it imports, dependencies first (the layout
/// `protoc --include_imports --descriptor_set_out` gives), serialized.
std::string DescriptorSet(const google::protobuf::Descriptor* d) {
  google::protobuf::FileDescriptorSet set;
  std::set<std::string> seen;
  auto add = [&](auto&& self, const google::protobuf::FileDescriptor* f) -> void {
    if (!seen.insert(f->name()).second) return;
    for (int i = 0; i < f->dependency_count(); ++i) self(self, f->dependency(i));
    f->CopyTo(set.add_file());
  };
  add(add, d->file());
  return set.SerializeAsString();
}

std::span<const uint8_t> Bytes(const std::string& s) {
  return {reinterpret_cast<const uint8_t*>(s.data()), s.size()};
}

void SetStamp(google::protobuf::Timestamp* ts, uint64_t ns) {
  ts->set_seconds(static_cast<int64_t>(ns / 1'000'000'000));
  ts->set_nanos(static_cast<int32_t>(ns % 1'000'000'000));
}

int Fail(const std::string& what) {
  std::fprintf(stderr, "write_sample: %s\n", what.c_str());
  return 1;
}

std::string Counts(const std::map<std::string, uint64_t>& m) {
  std::string s = "{";
  for (const auto& [topic, n] : m) {
    if (s.size() > 1) s += ", ";
    s += "\"" + topic + "\": " + std::to_string(n);
  }
  return s + "}";
}

}  // namespace

int main(int argc, char** argv) {
  std::string out, report_path;
  Compression compression = Compression::kZstd;
  double seconds = 2.0;
  rheo::record::WriterOptions options;
  bool truncate = false, verify = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "write_sample: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--out") {
      out = value();
    } else if (a == "--report") {
      report_path = value();
    } else if (a == "--compression") {
      const std::string c = value();
      if (c == "zstd") {
        compression = Compression::kZstd;
      } else if (c == "lz4") {
        compression = Compression::kLz4;
      } else if (c == "none") {
        compression = Compression::kNone;
      } else {
        return Fail("--compression is zstd, lz4 or none, not " + c);
      }
    } else if (a == "--seconds") {
      seconds = std::stod(value());
    } else if (a == "--chunk-size") {
      options.chunk_size = std::stoull(value());
    } else if (a == "--zstd-level") {
      options.zstd_level = std::stoi(value());
    } else if (a == "--truncate") {
      truncate = true;
    } else if (a == "--verify") {
      verify = true;
    } else {
      return Fail("unknown argument " + a + " (see the comment at the top of write_sample.cc)");
    }
  }
  if (out.empty()) return Fail("--out FILE is required");
  options.compression = compression;

  auto sink = rheo::record::FileSink::Create(out);
  if (!sink.ok()) return Fail(sink.error().message);
  McapWriter w;
  using Clock = std::chrono::steady_clock;
  Clock::duration in_writer{};
  auto timed = [&](auto&& call) {
    const auto t0 = Clock::now();
    auto r = call();
    in_writer += Clock::now() - t0;
    return r;
  };

  if (auto s = w.Open(**sink, "", "rheo write_sample", options); !s.ok()) {
    return Fail(s.error().message);
  }
  auto tool_schema = w.AddSchema(sample::ToolSample::descriptor()->full_name(), "protobuf",
                                 Bytes(DescriptorSet(sample::ToolSample::descriptor())));
  auto frame_schema = w.AddSchema(sample::Frame::descriptor()->full_name(), "protobuf",
                                  Bytes(DescriptorSet(sample::Frame::descriptor())));
  if (!tool_schema.ok() || !frame_schema.ok()) return Fail("AddSchema failed");
  auto tool = w.AddChannel(*tool_schema, "/tool/sample", "protobuf", {{"rate_hz", "1000"}});
  auto frame = w.AddChannel(*frame_schema, "/studio/frame", "protobuf", {{"rate_hz", "60"}});
  if (!tool.ok() || !frame.ok()) return Fail("AddChannel failed");

  // Per chunk: where it starts and ends in the file, and the messages in the chunks up to it.
  struct ChunkMark {
    uint64_t start, end;
    std::map<std::string, uint64_t> complete;
  };
  std::vector<ChunkMark> marks;
  std::map<std::string, uint64_t> written;
  uint64_t payload_bytes = 0;
  auto write = [&](uint16_t channel, const std::string& topic, uint32_t seq, uint64_t t,
                   const std::string& bytes) -> rheo::Status {
    const uint64_t before = w.bytes_written();
    const uint32_t chunks = w.chunk_count();
    rheo::Status s = timed([&] { return w.Write(channel, seq, t, t, Bytes(bytes)); });
    if (!s.ok()) return s;
    ++written[topic];
    payload_bytes += bytes.size();
    if (w.chunk_count() != chunks) marks.push_back({before, w.bytes_written(), written});
    return s;
  };

  const uint64_t t0 = 1'760'000'000'000'000'000ull;  // CLOCK_REALTIME-like [ns]
  const int ticks = static_cast<int>(seconds * 1000);
  const int width = 320, height = 320;  // 102,400 bytes a frame
  sample::ToolSample ts;
  sample::Frame fr;
  std::string buf, pixels(width * height, '\0');
  uint32_t noise = 12345, frames = 0;
  for (int i = 0; i < ticks; ++i) {
    const uint64_t t = t0 + uint64_t(i) * 1'000'000;
    ts.Clear();
    ts.set_sequence(i);
    SetStamp(ts.mutable_stamp(), t);
    for (int k = 0; k < 3; ++k) ts.add_position(0.01 * k + 1e-4 * i);
    for (int k = 0; k < 3; ++k) ts.add_force(0.5 * k - 1e-3 * (i % 100));
    for (int k = 0; k < 32; ++k) ts.add_displacement(1e-4f * float((i + k) % 50));
    ts.SerializeToString(&buf);
    if (auto s = write(*tool, "/tool/sample", i, t, buf); !s.ok()) return Fail(s.error().message);
    if ((i * 60) / 1000 != ((i + 1) * 60) / 1000) {  // 60 Hz
      for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
          noise = noise * 1664525u + 1013904223u;
          pixels[y * width + x] =
              static_cast<char>(((x * 3 + y * 5 + int(frames) * 7) & 0xfc) | (noise >> 30));
        }
      }
      fr.Clear();
      fr.set_sequence(frames);
      SetStamp(fr.mutable_stamp(), t);
      fr.set_width(width);
      fr.set_height(height);
      fr.set_pixels(pixels);
      fr.SerializeToString(&buf);
      if (auto s = write(*frame, "/studio/frame", frames, t, buf); !s.ok()) {
        return Fail(s.error().message);
      }
      ++frames;
    }
  }
  if (auto s = timed([&] { return w.Close(); }); !s.ok()) return Fail(s.error().message);
  if (auto s = (*sink)->Close(); !s.ok()) return Fail(s.error().message);
  const uint64_t size = w.bytes_written();
  const double write_s = std::chrono::duration<double>(in_writer).count();

  std::map<std::string, uint64_t> expected = written;
  std::string truncated_at = "null";
  if (truncate) {
    if (marks.size() < 3) return Fail("--truncate needs at least 3 chunks; raise --seconds");
    const size_t k = marks.size() / 2;
    const uint64_t cut = marks[k].start + (marks[k].end - marks[k].start) / 3;
    if (::truncate(out.c_str(), static_cast<off_t>(cut)) != 0) {
      return Fail("truncate " + out + ": " + std::strerror(errno));
    }
    expected = marks[k - 1].complete;
    for (const auto& [topic, n] : written) expected.try_emplace(topic, 0);
    truncated_at = std::to_string(cut);
  }

  std::string read_report;
  if (verify) {
    const auto r0 = Clock::now();
    auto reader = rheo::record::McapReader::OpenFile(out);
    if (!reader.ok()) return Fail("McapReader: " + reader.error().message);
    if (reader->truncation().has_value() != truncate) {
      return Fail(truncate ? "McapReader did not see the cut"
                           : "McapReader calls the file truncated");
    }
    std::map<std::string, uint64_t> read;
    uint64_t last = 0;
    rheo::Status s = reader->ForEachMessage([&](const rheo::record::Message& m) -> rheo::Status {
      ++read[m.channel->topic];
      uint32_t seq;
      const google::protobuf::Timestamp* stamp;
      if (m.channel->topic == "/tool/sample") {
        if (!ts.ParseFromArray(m.data.data(), static_cast<int>(m.data.size()))) {
          return rheo::DataLoss("a ToolSample does not parse");
        }
        seq = ts.sequence();
        stamp = &ts.stamp();
      } else {
        if (!fr.ParseFromArray(m.data.data(), static_cast<int>(m.data.size()))) {
          return rheo::DataLoss("a Frame does not parse");
        }
        seq = fr.sequence();
        stamp = &fr.stamp();
      }
      const uint64_t ns = uint64_t(stamp->seconds()) * 1'000'000'000 + uint64_t(stamp->nanos());
      if (seq != m.sequence || ns != m.log_time || m.log_time < last) {
        return rheo::DataLoss(m.channel->topic + " #" + std::to_string(m.sequence) +
                              ": payload or order does not match the record");
      }
      last = m.log_time;
      return rheo::Status::Ok();
    });
    if (!s.ok()) return Fail("McapReader: " + s.error().message);
    for (const auto& [topic, n] : expected) {
      if (read[topic] != n) {
        return Fail("McapReader read " + std::to_string(read[topic]) + " messages on " + topic +
                    ", the writer says " + std::to_string(n));
      }
    }
    const double read_s = std::chrono::duration<double>(Clock::now() - r0).count();
    read_report =
        ", \"read_s\": " + std::to_string(read_s) + ", \"read_per_topic\": " + Counts(read);
  }

  const double mib = 1024.0 * 1024.0;
  char timing[512];
  std::snprintf(timing, sizeof timing,
                "\"bytes\": %llu, \"payload_bytes\": %llu, \"chunks\": %u, \"recorded_s\": %.3f, "
                "\"write_s\": %.4f, \"file_mib_per_s\": %.1f, \"payload_mib_per_s\": %.1f, "
                "\"ratio\": %.3f",
                static_cast<unsigned long long>(size),
                static_cast<unsigned long long>(payload_bytes), w.chunk_count(), ticks / 1000.0,
                write_s, size / mib / write_s, payload_bytes / mib / write_s,
                double(size) / double(payload_bytes));
  const std::string report = "{\"file\": \"" + out + "\", \"compression\": \"" +
                             std::string(rheo::record::CompressionName(compression)) +
                             "\", \"chunk_size\": " + std::to_string(options.chunk_size) + ", " +
                             timing + ", \"messages\": " + std::to_string(w.message_count()) +
                             ", \"per_topic\": " + Counts(written) +
                             ", \"truncated_at\": " + truncated_at +
                             ", \"expected_per_topic\": " + Counts(expected) + read_report + "}\n";
  std::fputs(report.c_str(), stdout);
  if (!report_path.empty()) {
    std::ofstream f(report_path);
    f << report;
    if (!f) return Fail("cannot write " + report_path);
  }
  return 0;
}
