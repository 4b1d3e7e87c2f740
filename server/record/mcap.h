// MCAP recording of haptic sessions: a chunked, indexed, compressed writer and a reader that
// iterates a file's messages in log-time order and recovers every complete chunk of a file cut
// short (a crash, a kill -9, a full disk). Written from the MCAP specification, major version 0
// (https://mcap.dev/spec), so Foxglove, rosbag2 and @mcap/core read what we write.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/status.h"

namespace rheo::record {

/// How a Chunk's records are compressed. kLz4 is the LZ4 frame format and kZstd a zstd frame, the
/// two the MCAP registry names; kNone stores the records as they are.
enum class Compression { kNone, kZstd, kLz4 };

/// The name a Chunk record stores for `c`: "", "zstd" or "lz4".
std::string_view CompressionName(Compression c);

/// Largest uncompressed chunk the writer makes and the reader accepts [bytes]. A chunk header
/// claiming more is taken as corruption instead of being allocated.
inline constexpr uint64_t kMaxChunkBytes = uint64_t{1} << 30;

// ---------------------------------------------------------------------------------------------
// Sinks

/// Where a writer's bytes go. The writer calls Write with consecutive pieces of the file and Flush
/// after each chunk and at Close.
class ByteSink {
 public:
  virtual ~ByteSink() = default;
  /// Appends `bytes` to the output. An error stops the recording (the writer repeats it).
  virtual Status Write(std::span<const uint8_t> bytes) = 0;
  /// Makes everything written so far durable.
  virtual Status Flush() = 0;
};

/// A file on a POSIX file system. Writes go straight to the file descriptor (no user-space buffer)
/// and Flush is fdatasync, so every chunk the writer has finished is on disk: a process killed
/// with SIGKILL, or a machine that loses power after the flush, leaves a file McapReader reads up
/// to the last complete chunk. Errors name the file; a full disk also says how much space is left.
class FileSink final : public ByteSink {
 public:
  /// Creates (or truncates) `path` for writing, mode 0644.
  static Result<std::unique_ptr<FileSink>> Create(const std::string& path);
  ~FileSink() override;
  FileSink(const FileSink&) = delete;
  FileSink& operator=(const FileSink&) = delete;

  Status Write(std::span<const uint8_t> bytes) override;
  Status Flush() override;
  /// Syncs and closes the file; later writes fail. The destructor closes without syncing.
  Status Close();

  const std::string& path() const { return path_; }
  uint64_t bytes_written() const { return written_; }

 private:
  FileSink(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  Status WriteError(int err) const;

  int fd_ = -1;
  std::string path_;
  uint64_t written_ = 0;  // bytes written through this sink [bytes]
};

/// Collects the file in memory (tests, small captures, sending a recording over the network).
class MemorySink final : public ByteSink {
 public:
  Status Write(std::span<const uint8_t> bytes) override;
  Status Flush() override { return Status::Ok(); }
  const std::vector<uint8_t>& bytes() const { return bytes_; }
  std::vector<uint8_t> Take() { return std::move(bytes_); }

 private:
  std::vector<uint8_t> bytes_;
};

// ---------------------------------------------------------------------------------------------
// Writer

struct WriterOptions {
  Compression compression = Compression::kZstd;
  /// A chunk is closed, compressed, written and flushed once its uncompressed records reach this
  /// size [bytes], 1 .. kMaxChunkBytes. It bounds what a crash can lose and what a reader must
  /// decompress at once. The default, 1 MiB, is ~0.17 s of 60 Hz 100 kB frames.
  uint64_t chunk_size = uint64_t{1} << 20;
  /// zstd compression level, 1 (fastest) .. 19; 3 is zstd's own default. Unused by kNone/kLz4.
  int zstd_level = 3;
};

/// Writes one MCAP file: Header, then chunks of messages (each followed by its Message Index
/// records), and at Close the Data End record, the summary (Schema and Channel records repeated,
/// Statistics, Chunk Index records), the Summary Offset records and the Footer. Schema and Channel
/// records are written into the data section when they are added, ahead of any chunk that uses
/// them, so a file cut anywhere still decodes. Messages are buffered into one reused chunk buffer
/// and compressed into another, so Write allocates only while the buffers grow to their working
/// size. One thread at a time; after any sink error every call returns that error.
class McapWriter {
 public:
  McapWriter();
  ~McapWriter();  // does not Close: an unclosed file reads as truncated after its last chunk
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Starts a file on `sink` (which must outlive the writer) with the Header's `profile` (""
  /// for none; "ros1"/"ros2" are the registry's) and `library` (who wrote it, e.g. "rheod 0.1").
  Status Open(ByteSink& sink, std::string_view profile, std::string_view library,
              const WriterOptions& options = {});

  /// Adds a schema: `name` is the message type ("rheo.v1.Frame"), `encoding` the schema encoding
  /// ("protobuf": `data` is a serialized google.protobuf.FileDescriptorSet; "" for none).
  /// @return its id, from 1.
  Result<uint16_t> AddSchema(std::string_view name, std::string_view encoding,
                             std::span<const uint8_t> data);

  /// Adds a channel on `topic` whose messages use `message_encoding` ("protobuf", "json", ...)
  /// and the schema `schema_id` (0: no schema). @return its id, from 1.
  Result<uint16_t> AddChannel(uint16_t schema_id, std::string_view topic,
                              std::string_view message_encoding,
                              const std::map<std::string, std::string>& metadata = {});

  /// Appends one message. Times are nanoseconds since an epoch the profile or the application
  /// defines (Rheo: CLOCK_REALTIME); they need not increase. `sequence` is the publisher's counter.
  Status Write(uint16_t channel_id, uint32_t sequence, uint64_t log_time_ns,
               uint64_t publish_time_ns, std::span<const uint8_t> data);

  /// Closes the current chunk now (if it holds messages), so everything written so far is in the
  /// file and flushed; the next message starts a new chunk.
  Status FlushChunk();

  /// Writes the last chunk, the Data End record, the summary and the footer, and flushes.
  Status Close();

  bool is_open() const;
  uint64_t bytes_written() const;  // bytes handed to the sink so far [bytes]
  uint64_t message_count() const;
  uint32_t chunk_count() const;  // chunks written so far (the open one not counted)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// ---------------------------------------------------------------------------------------------
// Reader

struct Header {
  std::string profile;
  std::string library;
};

struct Schema {
  uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::vector<uint8_t> data;
};

struct Channel {
  uint16_t id = 0;
  uint16_t schema_id = 0;  // 0: no schema
  std::string topic;
  std::string message_encoding;
  std::map<std::string, std::string> metadata;
};

/// The summary's Statistics record.
struct Statistics {
  uint64_t message_count = 0;
  uint16_t schema_count = 0;
  uint32_t channel_count = 0;
  uint32_t attachment_count = 0;
  uint32_t metadata_count = 0;
  uint32_t chunk_count = 0;
  uint64_t message_start_time = 0;  // earliest log time [ns]; 0 without messages
  uint64_t message_end_time = 0;    // latest log time [ns]; 0 without messages
  std::map<uint16_t, uint64_t> channel_message_counts;
};

/// A Chunk record found in the data section.
struct ChunkInfo {
  uint64_t offset = 0;  // of the Chunk record from the start of the file [bytes]
  uint64_t length = 0;  // of the whole record, opcode and length prefix included [bytes]
  uint64_t message_start_time = 0;  // [ns]
  uint64_t message_end_time = 0;    // [ns]
  Compression compression = Compression::kNone;
  uint64_t compressed_size = 0;    // of the records field as stored [bytes]
  uint64_t uncompressed_size = 0;  // [bytes]
  uint32_t uncompressed_crc = 0;   // 0: not stored
};

/// Where and why a file ends early.
struct Truncation {
  uint64_t valid_bytes = 0;  // bytes [0, valid_bytes) of the file are whole records
  std::string reason;        // e.g. "the Chunk record at offset 123456 is cut: ..."
};

/// One message, resolved. `data` points into the file or into a decompressed chunk and stays
/// valid until the cursor's next Next().
struct Message {
  const Channel* channel = nullptr;  // never null
  const Schema* schema = nullptr;    // null when the channel has no schema
  uint32_t sequence = 0;
  uint64_t log_time = 0;      // [ns]
  uint64_t publish_time = 0;  // [ns]
  std::span<const uint8_t> data;
  uint64_t chunk_offset = 0;  // the holding Chunk record's file offset (outside chunks: the
                              // offset of the run of records the message is in) [bytes]
};

class MessageCursor;

/// Reads an MCAP file held in memory or mapped from disk. Open checks the magic and the structure,
/// reads the summary through the footer (checking its CRC and the data section's), and lists the
/// chunks. A file without a footer (a recording that was not closed, or was cut) is scanned
/// forward: every complete chunk is kept and truncation() says where and why the file ends.
/// Messages() then yields every message in log-time order (ties in file order), decompressing
/// only the chunks whose time ranges overlap the message being returned and checking each chunk's
/// CRC. Not thread-safe; a cursor must not outlive its reader.
class McapReader {
 public:
  /// Maps the file at `path` read-only. The file must not shrink while the reader exists.
  static Result<McapReader> OpenFile(const std::string& path);
  /// Reads a whole file held in `bytes`; `name` labels error messages.
  static Result<McapReader> OpenBuffer(std::vector<uint8_t> bytes, std::string name = "<memory>");
  /// Like OpenBuffer, but `bytes` must outlive the reader (no copy).
  static Result<McapReader> OpenView(std::span<const uint8_t> bytes, std::string name = "<memory>");

  McapReader(McapReader&&) noexcept;
  McapReader& operator=(McapReader&&) noexcept;
  ~McapReader();

  const Header& header() const;
  const std::map<uint16_t, Schema>& schemas() const;
  const std::map<uint16_t, Channel>& channels() const;
  /// The summary's Statistics; absent without a summary (e.g. truncated).
  const std::optional<Statistics>& statistics() const;
  /// Every complete Chunk record, in file order.
  const std::vector<ChunkInfo>& chunks() const;
  bool has_summary() const;
  /// Set when the file has no footer: it was not closed or was cut.
  const std::optional<Truncation>& truncation() const;
  uint64_t file_size() const;

  /// A cursor over every message in log-time order.
  MessageCursor Messages();
  /// Calls `fn` for every message in log-time order; stops at the first error, its own included.
  Status ForEachMessage(const std::function<Status(const Message&)>& fn);

  struct Impl;

 private:
  explicit McapReader(std::unique_ptr<Impl> impl);
  static Result<McapReader> Open(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Pulls messages one at a time (rheo replay paces them by log time).
class MessageCursor {
 public:
  MessageCursor(MessageCursor&&) noexcept;
  MessageCursor& operator=(MessageCursor&&) noexcept;
  ~MessageCursor();

  /// The next message, or nullptr after the last. Errors (a CRC mismatch, a chunk that does not
  /// decompress, a message on an undefined channel) name the chunk's offset; after one, every
  /// call returns it again.
  Result<const Message*> Next();

  struct State;

 private:
  friend class McapReader;
  explicit MessageCursor(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace rheo::record
