#pragma once
// MCAP files (https://mcap.dev/spec, the format `ros2 bag` writes by default; issue 24): a
// streaming writer and a validating reader, written from the specification (no C++ MCAP library
// is packaged in Debian). The writer puts Schema, Channel and Message records into uncompressed
// Chunks of bounded size, each followed by its MessageIndex records, then DataEnd with the data
// section's CRC32, and a summary section (Schemas, Channels, Statistics, ChunkIndexes, one
// SummaryOffset per group) and a Footer with the summary's CRC32. Memory: one chunk buffer (at
// most chunk_size_bytes plus one message) and one ChunkIndex per chunk written.
//
// The reader checks both magics, the summary CRC, each chunk's CRC, and (on a linear scan) the
// data section CRC; it reads through the summary's ChunkIndexes when present (skipping chunks
// without the wanted channels) and falls back to a linear scan of the data section otherwise.
// Errors name the file, the byte offset and the record.

#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace felt {

/// The 8 bytes at both ends of an MCAP file: 0x89 "MCAP" '0' "\r\n" (spec: Magic).
inline constexpr uint8_t kMcapMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};

/// CRC-32 (ISO-HDLC / IEEE 802.3: reflected polynomial 0xEDB88320, initial and final xor
/// 0xFFFFFFFF; what MCAP specifies) of `bytes`, continuing from `crc` (0 to start).
uint32_t Crc32(std::span<const uint8_t> bytes, uint32_t crc = 0);

/// A malformed or unreadable MCAP file. what() reads "FILE: byte OFFSET: RECORD: message".
class McapError : public std::runtime_error {
 public:
  McapError(const std::string& file, uint64_t offset, const std::string& record,
            const std::string& message);
  uint64_t offset() const { return offset_; }  ///< byte offset in the file

 private:
  uint64_t offset_;
};

/// A Schema record.
struct McapSchema {
  uint16_t id = 0;       ///< > 0
  std::string name;      ///< e.g. "geometry_msgs/msg/PoseStamped"
  std::string encoding;  ///< e.g. "ros2msg"
  std::string data;      ///< the schema text
};

/// A Channel record.
struct McapChannel {
  uint16_t id = 0;
  uint16_t schema_id = 0;                                     ///< 0 = no schema
  std::string topic;                                          ///< e.g. "/default/measured_cp"
  std::string message_encoding;                               ///< e.g. "cdr"
  std::vector<std::pair<std::string, std::string>> metadata;  ///< key order kept
};

/// A Message record; `data` points into the reader's buffer (valid during the callback only).
struct McapMessage {
  uint16_t channel_id = 0;
  uint32_t sequence = 0;
  uint64_t log_time_ns = 0;      ///< when it was logged [ns]
  uint64_t publish_time_ns = 0;  ///< when it was published [ns]
  std::span<const uint8_t> data;
  uint64_t file_offset = 0;  ///< where its record starts (in the chunk's data for chunked
                             ///< files: the chunk's offset + 1 + 8 + header + offset inside)
};

/// How an McapWriter writes.
struct McapWriterOptions {
  std::string profile = "ros2";       ///< the Header's profile
  std::string library = "felt";       ///< the Header's library
  size_t chunk_size_bytes = 1 << 20;  ///< a chunk is written once its records reach this size
};

/// What an McapWriter wrote.
struct McapWriterStats {
  uint64_t messages = 0;       ///< Message records
  uint64_t chunks = 0;         ///< Chunk records
  uint64_t bytes = 0;          ///< file size so far
  size_t max_chunk_bytes = 0;  ///< the largest chunk's records [bytes] (memory held)
};

/// Closes a C stream (for std::unique_ptr): a file is closed however its owner's constructor or
/// reading ends.
struct McapFileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
/// An owned C stream.
using McapFile = std::unique_ptr<std::FILE, McapFileCloser>;

/// Writes an MCAP file as it goes (see the file comment). One thread uses an instance. Not
/// real-time: it allocates and writes files; feed it from a queue (transport/mcap_recorder.h).
class McapWriter {
 public:
  /// Creates (truncates) `path` and writes the magic and the Header. Throws std::runtime_error
  /// naming the file when it cannot be created; std::invalid_argument for a chunk size of 0.
  McapWriter(std::string path, McapWriterOptions options = {});
  /// Closes the file if Close was not called (an error there is lost: call Close).
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Registers a schema; returns its id (1, 2, ...).
  uint16_t AddSchema(std::string_view name, std::string_view encoding, std::string_view data);
  /// Registers a channel on schema `schema_id` (0 = none); returns its id (0, 1, ...). Throws
  /// std::invalid_argument for an unknown schema id.
  uint16_t AddChannel(uint16_t schema_id, std::string_view topic, std::string_view encoding,
                      const std::vector<std::pair<std::string, std::string>>& metadata = {});
  /// Appends a message to the current chunk (writing the chunk when it is full). Throws
  /// std::invalid_argument for an unknown channel, std::runtime_error when a write fails.
  void WriteMessage(uint16_t channel_id, uint32_t sequence, uint64_t log_time_ns,
                    uint64_t publish_time_ns, std::span<const uint8_t> data);
  /// Writes the last chunk, DataEnd, the summary, the Footer and the closing magic, then closes
  /// the file. Throws std::runtime_error naming the file when a write failed. Once only.
  void Close();
  /// The counters so far.
  const McapWriterStats& stats() const { return stats_; }

 private:
  void FlushChunk();
  void WriteOut(std::span<const uint8_t> bytes, bool data_section);
  struct ChunkIndex {
    uint64_t start_time = 0, end_time = 0, offset = 0, length = 0;
    std::vector<std::pair<uint16_t, uint64_t>> message_index_offsets;
    uint64_t message_index_length = 0, size = 0;
  };

  std::string path_;
  McapWriterOptions options_;
  McapFile file_;
  bool failed_ = false;
  uint64_t offset_ = 0;    // bytes written
  uint32_t data_crc_ = 0;  // CRC32 of the data section so far
  std::vector<McapSchema> schemas_;
  std::vector<McapChannel> channels_;
  std::vector<uint8_t> chunk_;  // the current chunk's records (reused)
  bool chunk_open_ = false;
  uint64_t chunk_start_time_ = 0, chunk_end_time_ = 0;
  // Per channel: (log time, offset in chunk_) of the current chunk's messages.
  std::vector<std::vector<std::pair<uint64_t, uint64_t>>> chunk_index_;
  std::vector<uint8_t> record_;  // scratch for one record (reused)
  std::vector<ChunkIndex> chunk_indexes_;
  std::vector<uint64_t> channel_counts_;
  uint64_t first_time_ = UINT64_MAX, last_time_ = 0;
  McapWriterStats stats_;
  bool closed_ = false;
};

/// Reads an MCAP file (see the file comment). Holds the file open; memory: one chunk or record
/// at a time, plus the summary.
class McapReader {
 public:
  /// Opens `path`, checks the leading magic and the Header, then the Footer, the closing magic
  /// and the summary (its CRC; Schema, Channel, Statistics and ChunkIndex records) when present.
  /// A file without a usable summary (no Footer, summary_start 0, truncated) is read by a linear
  /// scan. Throws McapError.
  explicit McapReader(std::string path);
  ~McapReader();
  McapReader(const McapReader&) = delete;
  McapReader& operator=(const McapReader&) = delete;

  /// Schemas and channels by id: the summary's, or (without one) those found by a scan of the
  /// whole file made here.
  const std::map<uint16_t, McapSchema>& schemas() const { return schemas_; }
  const std::map<uint16_t, McapChannel>& channels() const { return channels_; }
  /// The Header's profile.
  const std::string& profile() const { return profile_; }
  /// True when messages are found through the summary's ChunkIndex records.
  bool indexed() const { return indexed_; }
  /// The Statistics record's message count (summary), or the count found by the scan.
  uint64_t message_count() const { return message_count_; }

  /// Calls `on_message` for each message, in file order, of the channels in `channel_ids` (all
  /// when empty). Through the index, chunks holding none of them are not read. Checks each
  /// chunk's CRC (and, on a linear scan, the data section's). Throws McapError.
  void ReadMessages(const std::function<void(const McapMessage&)>& on_message,
                    const std::vector<uint16_t>& channel_ids = {});

 private:
  struct ChunkRef {
    uint64_t offset = 0, length = 0;
    std::vector<uint16_t> channels;
  };
  void ReadSummary(uint64_t summary_start, uint64_t footer_offset, uint32_t summary_crc);
  void Scan(const std::function<void(const McapMessage&)>* on_message,
            const std::vector<uint16_t>& channel_ids);
  void ReadChunk(uint64_t offset, const std::function<void(const McapMessage&)>* on_message,
                 const std::vector<uint16_t>& channel_ids);
  void ReadAt(uint64_t offset, size_t n, std::vector<uint8_t>* out, const char* record);
  // A Schema, Channel or Message record's `body` (the record at file offset `at`; other ops are
  // skipped), in a chunk or the data section alike: schemas and channels kept (the first of an
  // id wins), a message counted (on_message null) or handed to on_message when its channel is
  // wanted (channel_ids empty: every channel).
  void ReadRecord(uint8_t op, std::span<const uint8_t> body, uint64_t at,
                  const std::function<void(const McapMessage&)>* on_message,
                  const std::vector<uint16_t>& channel_ids);

  std::string path_;
  McapFile file_;
  uint64_t size_ = 0;
  std::string profile_;
  bool indexed_ = false;
  uint64_t message_count_ = 0;
  std::map<uint16_t, McapSchema> schemas_;
  std::map<uint16_t, McapChannel> channels_;
  std::vector<ChunkRef> chunks_;
  std::vector<uint8_t> buffer_, chunk_buffer_;
};

}  // namespace felt
