#include "recordings/mcap.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstring>

namespace felt {

static_assert(std::endian::native == std::endian::little,
              "recordings/mcap.cc writes MCAP's little-endian integers as the host's bytes");

namespace {

// Record opcodes (MCAP specification, "Records").
enum McapOp : uint8_t {
  kOpHeader = 0x01,
  kOpFooter = 0x02,
  kOpSchema = 0x03,
  kOpChannel = 0x04,
  kOpMessage = 0x05,
  kOpChunk = 0x06,
  kOpMessageIndex = 0x07,
  kOpChunkIndex = 0x08,
  kOpStatistics = 0x0B,
  kOpSummaryOffset = 0x0E,
  kOpDataEnd = 0x0F,
};

const char* McapOpName(uint8_t op) {
  switch (op) {
    case kOpHeader:
      return "Header";
    case kOpFooter:
      return "Footer";
    case kOpSchema:
      return "Schema";
    case kOpChannel:
      return "Channel";
    case kOpMessage:
      return "Message";
    case kOpChunk:
      return "Chunk";
    case kOpMessageIndex:
      return "MessageIndex";
    case kOpChunkIndex:
      return "ChunkIndex";
    case 0x09:
      return "Attachment";
    case 0x0A:
      return "AttachmentIndex";
    case kOpStatistics:
      return "Statistics";
    case 0x0C:
      return "Metadata";
    case 0x0D:
      return "MetadataIndex";
    case kOpSummaryOffset:
      return "SummaryOffset";
    case kOpDataEnd:
      return "DataEnd";
    default:
      return "record";
  }
}

constexpr size_t kRecordPrefix = 9;  // opcode u8 + content length u64

// The CRC-32 table of the reflected polynomial 0xEDB88320 (Sarwate's byte-wise method).
const std::array<uint32_t, 256>& McapCrcTable() {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  return table;
}

// ---- Little-endian appenders.

// resize + memcpy (GCC 12's -Warray-bounds misfires on vector::insert of a few bytes).
void McapPutRaw(std::vector<uint8_t>* out, const void* p, size_t n) {
  if (n == 0) return;
  const size_t old = out->size();
  out->resize(old + n);
  std::memcpy(out->data() + old, p, n);
}

template <class T>
void McapPut(std::vector<uint8_t>* out, T v) {
  McapPutRaw(out, &v, sizeof(T));
}

void McapPutString(std::vector<uint8_t>* out, std::string_view s) {
  McapPut<uint32_t>(out, static_cast<uint32_t>(s.size()));
  McapPutRaw(out, s.data(), s.size());
}

// Starts a record in *out (opcode, a length patched by McapEndRecord); returns its start.
size_t McapBeginRecord(std::vector<uint8_t>* out, uint8_t op) {
  const size_t start = out->size();
  out->push_back(op);
  McapPut<uint64_t>(out, 0);
  return start;
}

void McapEndRecord(std::vector<uint8_t>* out, size_t start) {
  const uint64_t len = out->size() - start - kRecordPrefix;
  std::memcpy(out->data() + start + 1, &len, 8);
}

void McapPutSchema(std::vector<uint8_t>* out, const McapSchema& s) {
  const size_t r = McapBeginRecord(out, kOpSchema);
  McapPut<uint16_t>(out, s.id);
  McapPutString(out, s.name);
  McapPutString(out, s.encoding);
  McapPutString(out, s.data);  // uint32-length-prefixed bytes
  McapEndRecord(out, r);
}

void McapPutChannel(std::vector<uint8_t>* out, const McapChannel& c) {
  const size_t r = McapBeginRecord(out, kOpChannel);
  McapPut<uint16_t>(out, c.id);
  McapPut<uint16_t>(out, c.schema_id);
  McapPutString(out, c.topic);
  McapPutString(out, c.message_encoding);
  // Map<string, string>: uint32 byte length, then the entries.
  std::vector<uint8_t> map;
  for (const auto& [k, v] : c.metadata) {
    McapPutString(&map, k);
    McapPutString(&map, v);
  }
  McapPut<uint32_t>(out, static_cast<uint32_t>(map.size()));
  McapPutRaw(out, map.data(), map.size());
  McapEndRecord(out, r);
}

// ---- A bounds-checked reader of one record's bytes.

class McapCursor {
 public:
  McapCursor(std::span<const uint8_t> bytes, uint64_t file_offset, const std::string& path,
             const char* record)
      : bytes_(bytes), base_(file_offset), path_(path), record_(record) {}

  template <class T>
  T Get(const char* field) {
    Need(sizeof(T), field);
    T v;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  std::string String(const char* field) {
    const uint32_t n = Get<uint32_t>(field);
    Need(n, field);
    std::string s(reinterpret_cast<const char*>(bytes_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  std::span<const uint8_t> Take(uint64_t n, const char* field) {
    Need(n, field);
    const std::span<const uint8_t> s = bytes_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  size_t pos() const { return pos_; }
  size_t left() const { return bytes_.size() - pos_; }
  [[noreturn]] void Fail(const std::string& message) const {
    throw McapError(path_, base_ + pos_, record_, message);
  }

 private:
  void Need(uint64_t n, const char* field) {
    if (n > bytes_.size() - pos_) {
      Fail(std::string(field) + ": needs " + std::to_string(n) + " bytes, the record has " +
           std::to_string(bytes_.size() - pos_) + " left");
    }
  }
  std::span<const uint8_t> bytes_;
  uint64_t base_;
  size_t pos_ = 0;
  const std::string& path_;
  const char* record_;
};

McapSchema McapParseSchema(McapCursor& c) {
  McapSchema s;
  s.id = c.Get<uint16_t>("id");
  s.name = c.String("name");
  s.encoding = c.String("encoding");
  s.data = c.String("data");
  return s;
}

McapChannel McapParseChannel(McapCursor& c) {
  McapChannel ch;
  ch.id = c.Get<uint16_t>("id");
  ch.schema_id = c.Get<uint16_t>("schema_id");
  ch.topic = c.String("topic");
  ch.message_encoding = c.String("message_encoding");
  const uint32_t map_len = c.Get<uint32_t>("metadata");
  const size_t end = c.pos() + map_len;
  if (map_len > c.left())
    c.Fail("metadata: map of " + std::to_string(map_len) + " bytes runs past the record");
  while (c.pos() < end) {
    std::string k = c.String("metadata key");
    std::string v = c.String("metadata value");
    ch.metadata.emplace_back(std::move(k), std::move(v));
  }
  if (c.pos() != end) c.Fail("metadata: entries overrun the map's length");
  return ch;
}

}  // namespace

uint32_t Crc32(std::span<const uint8_t> bytes, uint32_t crc) {
  const std::array<uint32_t, 256>& t = McapCrcTable();
  uint32_t c = crc ^ 0xFFFFFFFFu;
  for (uint8_t b : bytes) c = t[(c ^ b) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

McapError::McapError(const std::string& file, uint64_t offset, const std::string& record,
                     const std::string& message)
    : std::runtime_error(file + ": byte " + std::to_string(offset) + ": " + record + ": " +
                         message),
      offset_(offset) {}

// ---- McapWriter ----

McapWriter::McapWriter(std::string path, McapWriterOptions options)
    : path_(std::move(path)), options_(std::move(options)) {
  if (options_.chunk_size_bytes == 0) {
    throw std::invalid_argument("McapWriterOptions.chunk_size_bytes: must be > 0");
  }
  file_.reset(std::fopen(path_.c_str(), "wb"));
  if (file_ == nullptr) {
    throw std::runtime_error(path_ + ": cannot create MCAP file: " + std::strerror(errno));
  }
  chunk_.reserve(options_.chunk_size_bytes + 4096);
  // Magic, then the Header record (profile, library).
  WriteOut(kMcapMagic, true);
  record_.clear();
  const size_t r = McapBeginRecord(&record_, kOpHeader);
  McapPutString(&record_, options_.profile);
  McapPutString(&record_, options_.library);
  McapEndRecord(&record_, r);
  WriteOut(record_, true);
}

McapWriter::~McapWriter() = default;  // file_ closes the file if Close did not

void McapWriter::WriteOut(std::span<const uint8_t> bytes, bool data_section) {
  if (data_section) data_crc_ = Crc32(bytes, data_crc_);
  if (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), file_.get()) != bytes.size()) {
    failed_ = true;
    throw std::runtime_error(path_ + ": MCAP write failed: " + std::strerror(errno));
  }
  offset_ += bytes.size();
  stats_.bytes = offset_;
}

uint16_t McapWriter::AddSchema(std::string_view name, std::string_view encoding,
                               std::string_view data) {
  McapSchema s{static_cast<uint16_t>(schemas_.size() + 1), std::string(name), std::string(encoding),
               std::string(data)};
  McapPutSchema(&chunk_, s);  // in the data section before any message that uses it
  schemas_.push_back(std::move(s));
  return schemas_.back().id;
}

uint16_t McapWriter::AddChannel(uint16_t schema_id, std::string_view topic,
                                std::string_view encoding,
                                const std::vector<std::pair<std::string, std::string>>& metadata) {
  if (schema_id > schemas_.size()) {
    throw std::invalid_argument("McapWriter::AddChannel: unknown schema id " +
                                std::to_string(schema_id));
  }
  McapChannel c{static_cast<uint16_t>(channels_.size()), schema_id, std::string(topic),
                std::string(encoding), metadata};
  McapPutChannel(&chunk_, c);
  channels_.push_back(std::move(c));
  chunk_index_.emplace_back();
  channel_counts_.push_back(0);
  return channels_.back().id;
}

void McapWriter::WriteMessage(uint16_t channel_id, uint32_t sequence, uint64_t log_time_ns,
                              uint64_t publish_time_ns, std::span<const uint8_t> data) {
  if (channel_id >= channels_.size()) {
    throw std::invalid_argument("McapWriter::WriteMessage: unknown channel id " +
                                std::to_string(channel_id));
  }
  if (closed_) throw std::runtime_error(path_ + ": MCAP writer is closed");
  // The message's offset in the chunk's records goes into its MessageIndex.
  chunk_index_[channel_id].emplace_back(log_time_ns, chunk_.size());
  const size_t r = McapBeginRecord(&chunk_, kOpMessage);
  McapPut<uint16_t>(&chunk_, channel_id);
  McapPut<uint32_t>(&chunk_, sequence);
  McapPut<uint64_t>(&chunk_, log_time_ns);
  McapPut<uint64_t>(&chunk_, publish_time_ns);
  McapPutRaw(&chunk_, data.data(), data.size());
  McapEndRecord(&chunk_, r);
  if (!chunk_open_) {
    chunk_open_ = true;
    chunk_start_time_ = chunk_end_time_ = log_time_ns;
  }
  chunk_start_time_ = std::min(chunk_start_time_, log_time_ns);
  chunk_end_time_ = std::max(chunk_end_time_, log_time_ns);
  first_time_ = std::min(first_time_, log_time_ns);
  last_time_ = std::max(last_time_, log_time_ns);
  ++channel_counts_[channel_id];
  ++stats_.messages;
  if (chunk_.size() >= options_.chunk_size_bytes) FlushChunk();
}

void McapWriter::FlushChunk() {
  if (chunk_.empty()) return;
  // The Chunk record: times, sizes, CRC32 of the records, compression "" (none), the records.
  ChunkIndex index;
  index.offset = offset_;
  index.start_time = chunk_open_ ? chunk_start_time_ : 0;
  index.end_time = chunk_open_ ? chunk_end_time_ : 0;
  index.size = chunk_.size();
  record_.clear();
  record_.push_back(kOpChunk);
  McapPut<uint64_t>(&record_, 8 + 8 + 8 + 4 + 4 + 8 + chunk_.size());
  McapPut<uint64_t>(&record_, index.start_time);
  McapPut<uint64_t>(&record_, index.end_time);
  McapPut<uint64_t>(&record_, chunk_.size());  // uncompressed_size
  McapPut<uint32_t>(&record_, Crc32(chunk_));  // uncompressed_crc
  McapPutString(&record_, "");                 // compression: none
  McapPut<uint64_t>(&record_, chunk_.size());  // records: uint64-length-prefixed bytes
  WriteOut(record_, true);
  WriteOut(chunk_, true);
  index.length = offset_ - index.offset;
  // One MessageIndex per channel with messages in this chunk, after the chunk.
  const uint64_t indexes_start = offset_;
  for (size_t ch = 0; ch < chunk_index_.size(); ++ch) {
    if (chunk_index_[ch].empty()) continue;
    index.message_index_offsets.emplace_back(static_cast<uint16_t>(ch), offset_);
    record_.clear();
    const size_t r = McapBeginRecord(&record_, kOpMessageIndex);
    McapPut<uint16_t>(&record_, static_cast<uint16_t>(ch));
    McapPut<uint32_t>(&record_, static_cast<uint32_t>(chunk_index_[ch].size() * 16));
    for (const auto& [t, off] : chunk_index_[ch]) {
      McapPut<uint64_t>(&record_, t);
      McapPut<uint64_t>(&record_, off);
    }
    McapEndRecord(&record_, r);
    WriteOut(record_, true);
    chunk_index_[ch].clear();
  }
  index.message_index_length = offset_ - indexes_start;
  chunk_indexes_.push_back(std::move(index));
  stats_.max_chunk_bytes = std::max(stats_.max_chunk_bytes, chunk_.size());
  ++stats_.chunks;
  chunk_.clear();
  chunk_open_ = false;
  // Bounded memory: what is written leaves this process's buffers.
  if (std::fflush(file_.get()) != 0) {
    failed_ = true;
    throw std::runtime_error(path_ + ": MCAP write failed: " + std::strerror(errno));
  }
}

void McapWriter::Close() {
  if (closed_) return;
  closed_ = true;
  FlushChunk();
  // DataEnd: the CRC32 of every byte before it (magic included).
  record_.clear();
  size_t r = McapBeginRecord(&record_, kOpDataEnd);
  McapPut<uint32_t>(&record_, data_crc_);
  McapEndRecord(&record_, r);
  WriteOut(record_, false);

  // The summary section, one group per record type, its CRC running from here.
  const uint64_t summary_start = offset_;
  uint32_t summary_crc = 0;
  struct Group {
    uint8_t op;
    uint64_t start, length;
  };
  std::vector<Group> groups;
  auto write_group = [&](uint8_t op, const std::vector<uint8_t>& bytes) {
    if (bytes.empty()) return;
    groups.push_back({op, offset_, bytes.size()});
    summary_crc = Crc32(bytes, summary_crc);
    WriteOut(bytes, false);
  };
  std::vector<uint8_t> group;
  for (const McapSchema& s : schemas_) McapPutSchema(&group, s);
  write_group(kOpSchema, group);
  group.clear();
  for (const McapChannel& c : channels_) McapPutChannel(&group, c);
  write_group(kOpChannel, group);
  group.clear();
  r = McapBeginRecord(&group, kOpStatistics);
  McapPut<uint64_t>(&group, stats_.messages);
  McapPut<uint16_t>(&group, static_cast<uint16_t>(schemas_.size()));
  McapPut<uint32_t>(&group, static_cast<uint32_t>(channels_.size()));
  McapPut<uint32_t>(&group, 0);  // attachments
  McapPut<uint32_t>(&group, 0);  // metadata
  McapPut<uint32_t>(&group, static_cast<uint32_t>(chunk_indexes_.size()));
  McapPut<uint64_t>(&group, stats_.messages ? first_time_ : 0);
  McapPut<uint64_t>(&group, stats_.messages ? last_time_ : 0);
  std::vector<uint8_t> counts;
  for (size_t ch = 0; ch < channel_counts_.size(); ++ch) {
    McapPut<uint16_t>(&counts, static_cast<uint16_t>(ch));
    McapPut<uint64_t>(&counts, channel_counts_[ch]);
  }
  McapPut<uint32_t>(&group, static_cast<uint32_t>(counts.size()));
  McapPutRaw(&group, counts.data(), counts.size());
  McapEndRecord(&group, r);
  write_group(kOpStatistics, group);
  group.clear();
  for (const ChunkIndex& ci : chunk_indexes_) {
    r = McapBeginRecord(&group, kOpChunkIndex);
    McapPut<uint64_t>(&group, ci.start_time);
    McapPut<uint64_t>(&group, ci.end_time);
    McapPut<uint64_t>(&group, ci.offset);
    McapPut<uint64_t>(&group, ci.length);
    McapPut<uint32_t>(&group, static_cast<uint32_t>(ci.message_index_offsets.size() * 10));
    for (const auto& [ch, off] : ci.message_index_offsets) {
      McapPut<uint16_t>(&group, ch);
      McapPut<uint64_t>(&group, off);
    }
    McapPut<uint64_t>(&group, ci.message_index_length);
    McapPutString(&group, "");
    McapPut<uint64_t>(&group, ci.size);  // compressed_size (no compression)
    McapPut<uint64_t>(&group, ci.size);  // uncompressed_size
    McapEndRecord(&group, r);
  }
  write_group(kOpChunkIndex, group);
  group.clear();
  // SummaryOffset records: where each group starts and how long it is.
  const uint64_t summary_offset_start = offset_;
  for (const Group& g : groups) {
    r = McapBeginRecord(&group, kOpSummaryOffset);
    McapPut<uint8_t>(&group, g.op);
    McapPut<uint64_t>(&group, g.start);
    McapPut<uint64_t>(&group, g.length);
    McapEndRecord(&group, r);
  }
  summary_crc = Crc32(group, summary_crc);
  WriteOut(group, false);
  // Footer: its CRC covers the summary section and the footer up to summary_offset_start.
  record_.clear();
  record_.push_back(kOpFooter);
  McapPut<uint64_t>(&record_, 20);
  McapPut<uint64_t>(&record_, summary_start);
  McapPut<uint64_t>(&record_, summary_offset_start);
  summary_crc = Crc32(record_, summary_crc);
  McapPut<uint32_t>(&record_, summary_crc);
  WriteOut(record_, false);
  WriteOut(kMcapMagic, false);
  const bool flushed = std::fflush(file_.get()) == 0;
  const bool closed = std::fclose(file_.release()) == 0;
  if (failed_ || !flushed || !closed) throw std::runtime_error(path_ + ": MCAP write failed");
}

// ---- McapReader ----

McapReader::McapReader(std::string path) : path_(std::move(path)) {
  file_.reset(std::fopen(path_.c_str(), "rb"));
  if (file_ == nullptr) {
    throw McapError(path_, 0, "file", std::string("cannot open: ") + std::strerror(errno));
  }
  if (std::fseek(file_.get(), 0, SEEK_END) != 0) throw McapError(path_, 0, "file", "cannot seek");
  size_ = static_cast<uint64_t>(std::ftell(file_.get()));
  // Leading magic and Header.
  if (size_ < sizeof(kMcapMagic) + kRecordPrefix) {
    throw McapError(path_, 0, "magic",
                    "file of " + std::to_string(size_) + " bytes is too short for MCAP");
  }
  ReadAt(0, sizeof(kMcapMagic), &buffer_, "magic");
  if (std::memcmp(buffer_.data(), kMcapMagic, sizeof(kMcapMagic)) != 0) {
    throw McapError(path_, 0, "magic",
                    "not an MCAP file (no leading magic 89 4D 43 41 50 30 0D 0A)");
  }
  ReadAt(8, kRecordPrefix, &buffer_, "Header");
  uint64_t len;
  std::memcpy(&len, buffer_.data() + 1, 8);
  if (buffer_[0] != kOpHeader) {
    throw McapError(path_, 8, "Header",
                    std::string("the first record is a ") + McapOpName(buffer_[0]) + " (opcode " +
                        std::to_string(buffer_[0]) + "), not a Header");
  }
  if (len > size_ - 8 - kRecordPrefix) {
    throw McapError(path_, 8, "Header",
                    "length " + std::to_string(len) + " runs past the end of the file");
  }
  ReadAt(8 + kRecordPrefix, len, &buffer_, "Header");
  {
    McapCursor c(buffer_, 8 + kRecordPrefix, path_, "Header");
    profile_ = c.String("profile");
    (void)c.String("library");
  }
  // Footer and closing magic; then the summary when there is one.
  constexpr uint64_t kFooterSize = kRecordPrefix + 20;
  bool have_summary = false;
  if (size_ >= 8 + 9 + kFooterSize + 8) {
    const uint64_t footer_offset = size_ - 8 - kFooterSize;
    ReadAt(footer_offset, kFooterSize + 8, &buffer_, "Footer");
    const bool magic_ok = std::memcmp(buffer_.data() + kFooterSize, kMcapMagic, 8) == 0;
    uint64_t flen, summary_start;
    uint32_t summary_crc;
    std::memcpy(&flen, buffer_.data() + 1, 8);
    std::memcpy(&summary_start, buffer_.data() + 9, 8);
    std::memcpy(&summary_crc, buffer_.data() + 25, 4);
    if (magic_ok && buffer_[0] == kOpFooter && flen == 20) {
      if (summary_start != 0) {
        if (summary_start < 8 + kRecordPrefix || summary_start > footer_offset) {
          throw McapError(
              path_, footer_offset, "Footer",
              "summary_start " + std::to_string(summary_start) + " lies outside the file's data");
        }
        ReadSummary(summary_start, footer_offset, summary_crc);
        have_summary = true;
      }
    }
  }
  if (!have_summary || !indexed_) {
    // No usable index: find the schemas and channels (and count the messages) by a scan.
    indexed_ = false;
    Scan(nullptr, {});
  }
}

McapReader::~McapReader() = default;

void McapReader::ReadAt(uint64_t offset, size_t n, std::vector<uint8_t>* out, const char* record) {
  if (offset > size_ || n > size_ - offset) {
    throw McapError(path_, offset, record,
                    "needs " + std::to_string(n) + " bytes, the file ends after " +
                        std::to_string(size_ - std::min(offset, size_)) + " (truncated?)");
  }
  out->resize(n);
  if (std::fseek(file_.get(), static_cast<long>(offset), SEEK_SET) != 0 ||
      (n > 0 && std::fread(out->data(), 1, n, file_.get()) != n)) {
    throw McapError(path_, offset, record, "read failed");
  }
}

void McapReader::ReadSummary(uint64_t summary_start, uint64_t footer_offset, uint32_t summary_crc) {
  std::vector<uint8_t> summary;
  ReadAt(summary_start, footer_offset - summary_start, &summary, "summary");
  // The summary CRC covers the summary section and the Footer up to summary_crc.
  if (summary_crc != 0) {
    std::vector<uint8_t> footer_prefix;
    ReadAt(footer_offset, kRecordPrefix + 16, &footer_prefix, "Footer");
    const uint32_t crc = Crc32(footer_prefix, Crc32(summary));
    if (crc != summary_crc) {
      throw McapError(path_, footer_offset, "Footer",
                      "summary CRC32 is " + std::to_string(crc) + ", the Footer says " +
                          std::to_string(summary_crc));
    }
  }
  uint64_t pos = 0;
  int64_t stats_chunks = -1;
  while (pos < summary.size()) {
    McapCursor head(std::span<const uint8_t>(summary).subspan(pos), summary_start + pos, path_,
                    "summary record");
    const uint8_t op = head.Get<uint8_t>("opcode");
    const uint64_t len = head.Get<uint64_t>("length");
    const uint64_t at = summary_start + pos;
    if (len > head.left()) {
      throw McapError(path_, at, McapOpName(op),
                      "length " + std::to_string(len) + " runs past the summary section");
    }
    McapCursor c(head.Take(len, "body"), at + kRecordPrefix, path_, McapOpName(op));
    if (op == kOpSchema) {
      McapSchema s = McapParseSchema(c);
      schemas_[s.id] = std::move(s);
    } else if (op == kOpChannel) {
      McapChannel ch = McapParseChannel(c);
      channels_[ch.id] = std::move(ch);
    } else if (op == kOpStatistics) {
      message_count_ = c.Get<uint64_t>("message_count");
      (void)c.Get<uint16_t>("schema_count");
      (void)c.Get<uint32_t>("channel_count");
      (void)c.Get<uint32_t>("attachment_count");
      (void)c.Get<uint32_t>("metadata_count");
      stats_chunks = c.Get<uint32_t>("chunk_count");
    } else if (op == kOpChunkIndex) {
      ChunkRef ref;
      (void)c.Get<uint64_t>("message_start_time");
      (void)c.Get<uint64_t>("message_end_time");
      ref.offset = c.Get<uint64_t>("chunk_start_offset");
      ref.length = c.Get<uint64_t>("chunk_length");
      const uint32_t map_len = c.Get<uint32_t>("message_index_offsets");
      if (map_len % 10 != 0) c.Fail("message_index_offsets: map length not a multiple of 10");
      for (uint32_t i = 0; i < map_len / 10; ++i) {
        ref.channels.push_back(c.Get<uint16_t>("message_index_offsets channel"));
        (void)c.Get<uint64_t>("message_index_offsets offset");
      }
      if (ref.offset >= summary_start || ref.length > summary_start - ref.offset) {
        c.Fail("chunk at " + std::to_string(ref.offset) + " (" + std::to_string(ref.length) +
               " bytes) lies outside the data section");
      }
      chunks_.push_back(std::move(ref));
    }
    pos += kRecordPrefix + len;
  }
  std::sort(chunks_.begin(), chunks_.end(),
            [](const ChunkRef& a, const ChunkRef& b) { return a.offset < b.offset; });
  // Read through the index only when it accounts for every chunk the Statistics count.
  indexed_ = !chunks_.empty() && (stats_chunks < 0 || stats_chunks == int64_t(chunks_.size()));
}

void McapReader::ReadChunk(uint64_t offset,
                           const std::function<void(const McapMessage&)>* on_message,
                           const std::vector<uint16_t>& channel_ids) {
  ReadAt(offset, kRecordPrefix, &chunk_buffer_, "Chunk");
  if (chunk_buffer_[0] != kOpChunk) {
    throw McapError(
        path_, offset, "Chunk",
        std::string("the index points at a ") + McapOpName(chunk_buffer_[0]) + ", not a Chunk");
  }
  uint64_t len;
  std::memcpy(&len, chunk_buffer_.data() + 1, 8);
  ReadAt(offset + kRecordPrefix, len, &chunk_buffer_, "Chunk");
  McapCursor c(chunk_buffer_, offset + kRecordPrefix, path_, "Chunk");
  (void)c.Get<uint64_t>("message_start_time");
  (void)c.Get<uint64_t>("message_end_time");
  const uint64_t uncompressed_size = c.Get<uint64_t>("uncompressed_size");
  const uint32_t crc = c.Get<uint32_t>("uncompressed_crc");
  const std::string compression = c.String("compression");
  const uint64_t records_len = c.Get<uint64_t>("records");
  const uint64_t records_at = offset + kRecordPrefix + c.pos();
  const std::span<const uint8_t> records = c.Take(records_len, "records");
  if (!compression.empty()) {
    throw McapError(path_, offset, "Chunk",
                    "compression '" + compression +
                        "' is not supported (Felt reads uncompressed chunks; convert with "
                        "`mcap compress --compression none` or record without compression)");
  }
  if (records_len != uncompressed_size) {
    throw McapError(path_, offset, "Chunk",
                    "records of " + std::to_string(records_len) + " bytes, uncompressed_size " +
                        std::to_string(uncompressed_size));
  }
  if (crc != 0 && Crc32(records) != crc) {
    throw McapError(path_, offset, "Chunk",
                    "CRC32 of the records is " + std::to_string(Crc32(records)) +
                        ", the chunk says " + std::to_string(crc));
  }
  // The records inside: Schema, Channel, Message.
  uint64_t pos = 0;
  while (pos < records.size()) {
    McapCursor head(records.subspan(pos), records_at + pos, path_, "record in Chunk");
    const uint8_t op = head.Get<uint8_t>("opcode");
    const uint64_t rlen = head.Get<uint64_t>("length");
    const uint64_t at = records_at + pos;
    if (rlen > head.left()) {
      throw McapError(path_, at, McapOpName(op),
                      "length " + std::to_string(rlen) + " runs past the end of its Chunk");
    }
    ReadRecord(op, head.Take(rlen, "body"), at, on_message, channel_ids);
    pos += kRecordPrefix + rlen;
  }
}

void McapReader::ReadRecord(uint8_t op, std::span<const uint8_t> body, uint64_t at,
                            const std::function<void(const McapMessage&)>* on_message,
                            const std::vector<uint16_t>& channel_ids) {
  McapCursor c(body, at + kRecordPrefix, path_, McapOpName(op));
  if (op == kOpSchema) {
    McapSchema s = McapParseSchema(c);
    if (!schemas_.count(s.id)) schemas_[s.id] = std::move(s);
  } else if (op == kOpChannel) {
    McapChannel ch = McapParseChannel(c);
    if (!channels_.count(ch.id)) channels_[ch.id] = std::move(ch);
  } else if (op == kOpMessage) {
    McapMessage m;
    m.channel_id = c.Get<uint16_t>("channel_id");
    m.sequence = c.Get<uint32_t>("sequence");
    m.log_time_ns = c.Get<uint64_t>("log_time");
    m.publish_time_ns = c.Get<uint64_t>("publish_time");
    m.data = c.Take(c.left(), "data");
    m.file_offset = at;
    if (!channels_.count(m.channel_id)) {
      throw McapError(path_, at, "Message",
                      "channel " + std::to_string(m.channel_id) +
                          " has no Channel record before it");
    }
    if (on_message == nullptr) {
      ++message_count_;
    } else if (channel_ids.empty() || std::find(channel_ids.begin(), channel_ids.end(),
                                                m.channel_id) != channel_ids.end()) {
      (*on_message)(m);
    }
  }
}

void McapReader::Scan(const std::function<void(const McapMessage&)>* on_message,
                      const std::vector<uint16_t>& channel_ids) {
  // A linear scan of the data section, record by record, its CRC32 checked at DataEnd.
  if (on_message == nullptr) message_count_ = 0;
  uint64_t pos = 8;
  uint32_t crc = Crc32(kMcapMagic);
  std::vector<uint8_t> head, body;
  while (true) {
    if (pos == size_) {
      throw McapError(path_, pos, "DataEnd",
                      "the file ends without DataEnd and Footer (truncated? a recording stopped "
                      "before it was closed)");
    }
    ReadAt(pos, kRecordPrefix, &head, "record");
    const uint8_t op = head[0];
    uint64_t len;
    std::memcpy(&len, head.data() + 1, 8);
    if (len > size_ - pos - kRecordPrefix) {
      throw McapError(path_, pos, McapOpName(op),
                      "length " + std::to_string(len) + " runs past the end of the file (" +
                          std::to_string(size_ - pos - kRecordPrefix) + " bytes left; truncated?)");
    }
    if (op == kOpDataEnd) {
      ReadAt(pos + kRecordPrefix, len, &body, "DataEnd");
      McapCursor c(body, pos + kRecordPrefix, path_, "DataEnd");
      const uint32_t want = c.Get<uint32_t>("data_section_crc");
      if (want != 0 && want != crc) {
        throw McapError(path_, pos, "DataEnd",
                        "data section CRC32 is " + std::to_string(crc) + ", DataEnd says " +
                            std::to_string(want));
      }
      return;
    }
    if (op == kOpFooter) return;
    if (op == kOpChunk) {
      ReadChunk(pos, on_message, channel_ids);
      crc = Crc32(head, crc);
      crc = Crc32(chunk_buffer_, crc);
    } else {
      ReadAt(pos + kRecordPrefix, len, &body, McapOpName(op));
      crc = Crc32(body, Crc32(head, crc));
      ReadRecord(op, body, pos, on_message, channel_ids);
    }
    pos += kRecordPrefix + len;
  }
}

void McapReader::ReadMessages(const std::function<void(const McapMessage&)>& on_message,
                              const std::vector<uint16_t>& channel_ids) {
  if (!indexed_) {
    Scan(&on_message, channel_ids);
    return;
  }
  for (const ChunkRef& ref : chunks_) {
    // Through the index: a chunk without any wanted channel is not read.
    if (!channel_ids.empty() &&
        std::none_of(ref.channels.begin(), ref.channels.end(), [&](uint16_t ch) {
          return std::find(channel_ids.begin(), channel_ids.end(), ch) != channel_ids.end();
        })) {
      continue;
    }
    ReadChunk(ref.offset, &on_message, channel_ids);
  }
}

}  // namespace felt
