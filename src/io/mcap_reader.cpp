// The MCAP reader. Every length, offset and count the file holds is checked
// against the bytes that are there (the file, the summary, the record, the
// chunk's content) before anything is allocated or read, and every CRC the
// file gives is checked; a chunk's content is decompressed into a buffer that
// grows as the stream produces it, up to the size the chunk claims and no more
// than kMaxChunkBytes or kMaxCompressionRatio times its compressed bytes.
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <functional>
#include <optional>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/mcap.hpp>

#include "decompress.hpp"
#include "mcap_format.hpp"

namespace dcl::io {

namespace {

using core::FileError;
using core::FileLocation;
using detail::kMcapMagic;
using detail::kMcapTailBytes;
using detail::kRecordPrefixBytes;
using detail::McapOp;

/// A chunk's content may be at most this large once decompressed (writers
/// make chunks of a few megabytes), and at most this many times its
/// compressed bytes (LZ4 reaches 255 at most; zstd on sensor data a few): a
/// few kilobytes of a hostile stream must not unfold into a gigabyte.
constexpr std::uint64_t kMaxChunkBytes = std::uint64_t{1} << 30;
constexpr std::uint64_t kMaxCompressionRatio = 1000;

std::string printable(std::string_view text) {
  std::string out;
  for (const char c : text.substr(0, 64)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  return out;
}

/// Reads the fields of bytes held in memory (a record's content, the summary,
/// a chunk's content), every read bounds-checked; a failure names the byte in
/// the file, or the chunk and the byte in its content.
class Cursor {
 public:
  /// `bytes` lie at `base` in the file, or at `base` in the content of the
  /// chunk whose record starts at `chunk` in the file.
  Cursor(std::span<const char> bytes, const std::string& path, std::uint64_t base,
         std::optional<std::uint64_t> chunk = std::nullopt)
      : bytes_(bytes), path_(path), base_(base), chunk_(chunk) {}

  template <class T>
  T number(const char* what) {
    T value{};
    std::memcpy(&value, take(sizeof(T), what).data(), sizeof(T));
    return value;
  }
  std::span<const char> take(std::uint64_t n, const char* what) {
    if (n > left()) {
      fail(fmt::format("{} of {} bytes runs past the end ({} bytes left)", what, n, left()));
    }
    const auto out = bytes_.subspan(at_, static_cast<std::size_t>(n));
    at_ += static_cast<std::size_t>(n);
    return out;
  }
  /// A string or byte array prefixed by its uint32 length.
  std::string string(const char* what) {
    const auto bytes = take(number<std::uint32_t>(what), what);
    return {bytes.data(), bytes.size()};
  }
  /// A map or array prefixed by its uint32 length in bytes, as a cursor of its own.
  Cursor group(const char* what) {
    const std::uint64_t at = base_ + at_ + 4;
    return {take(number<std::uint32_t>(what), what), path_, at, chunk_};
  }
  std::span<const char> rest() { return take(left(), "rest"); }

  [[nodiscard]] std::size_t left() const { return bytes_.size() - at_; }
  [[nodiscard]] std::uint64_t position() const { return base_ + at_; }

  [[noreturn]] void fail(const std::string& what) const { failAt(position(), what); }
  [[noreturn]] void failAt(std::uint64_t position, const std::string& what) const {
    if (chunk_) {
      io::failAtByte(path_, *chunk_,
                     fmt::format("chunk: at byte {} of its content: {}", position, what));
    }
    io::failAtByte(path_, position, what);
  }

 private:
  std::span<const char> bytes_;
  const std::string& path_;
  std::uint64_t base_;
  std::optional<std::uint64_t> chunk_;
  std::size_t at_ = 0;
};

/// One record read from a cursor: its opcode, where it starts and its content.
struct Record {
  McapOp op{};
  std::uint64_t at = 0;
  std::span<const char> content{};
};

/// The next record of `in`; none at its end.
std::optional<Record> nextRecord(Cursor& in) {
  if (in.left() == 0) return std::nullopt;
  Record r;
  r.at = in.position();
  r.op = static_cast<McapOp>(in.number<std::uint8_t>("record opcode"));
  r.content = in.take(in.number<std::uint64_t>("record length"), "record");
  return r;
}

McapSchema parseSchema(Cursor in) {
  McapSchema s;
  s.id = in.number<std::uint16_t>("schema id");
  s.name = in.string("schema name");
  s.encoding = in.string("schema encoding");
  s.data = in.string("schema data");
  if (s.id == 0) in.fail("schema id 0 (reserved for none)");
  return s;
}

McapChannel parseChannel(Cursor in) {
  McapChannel c;
  c.id = in.number<std::uint16_t>("channel id");
  c.schema_id = in.number<std::uint16_t>("channel schema id");
  c.topic = in.string("channel topic");
  c.message_encoding = in.string("channel message encoding");
  Cursor metadata = in.group("channel metadata");
  while (metadata.left() > 0) {
    std::string key = metadata.string("metadata key");
    c.metadata[std::move(key)] = metadata.string("metadata value");
  }
  return c;
}

McapMessage parseMessage(Cursor in) {
  McapMessage m;
  m.channel_id = in.number<std::uint16_t>("message channel id");
  m.sequence = in.number<std::uint32_t>("message sequence");
  m.log_time = in.number<std::uint64_t>("message log time");
  m.publish_time = in.number<std::uint64_t>("message publish time");
  const auto data = in.rest();
  m.data = {reinterpret_cast<const std::uint8_t*>(data.data()), data.size()};
  return m;
}

/// A chunk record's fields; `records` its (compressed) content.
struct ChunkFields {
  std::uint64_t uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;
  std::string compression{};
  std::span<const char> records{};
};

ChunkFields parseChunk(Cursor in) {
  ChunkFields c;
  in.number<std::uint64_t>("chunk message start time");
  in.number<std::uint64_t>("chunk message end time");
  c.uncompressed_size = in.number<std::uint64_t>("chunk uncompressed size");
  c.uncompressed_crc = in.number<std::uint32_t>("chunk uncompressed crc");
  c.compression = in.string("chunk compression");
  c.records = in.take(in.number<std::uint64_t>("chunk records length"), "chunk records");
  return c;
}

/// A chunk index's fields that locate and check its chunk and message indexes.
struct ChunkIndexFields {
  std::uint64_t at = 0;  ///< of the chunk index record, for messages
  std::uint64_t chunk_start = 0;
  std::uint64_t chunk_length = 0;
  std::uint64_t message_index_length = 0;
  std::string compression{};
  std::uint64_t compressed_size = 0;
  std::uint64_t uncompressed_size = 0;
};

ChunkIndexFields parseChunkIndex(Cursor in, std::uint64_t at) {
  ChunkIndexFields c;
  c.at = at;
  in.number<std::uint64_t>("chunk index message start time");
  in.number<std::uint64_t>("chunk index message end time");
  c.chunk_start = in.number<std::uint64_t>("chunk start offset");
  c.chunk_length = in.number<std::uint64_t>("chunk length");
  Cursor offsets = in.group("message index offsets");
  if (offsets.left() % 10 != 0) offsets.fail("message index offsets are not 10-byte entries");
  c.message_index_length = in.number<std::uint64_t>("message index length");
  c.compression = in.string("chunk index compression");
  c.compressed_size = in.number<std::uint64_t>("chunk index compressed size");
  c.uncompressed_size = in.number<std::uint64_t>("chunk index uncompressed size");
  return c;
}

/// What the statistics record says the file holds.
struct Statistics {
  std::uint64_t message_count = 0;
  std::uint32_t chunk_count = 0;
};

Statistics parseStatistics(Cursor in) {
  Statistics s;
  s.message_count = in.number<std::uint64_t>("statistics message count");
  in.number<std::uint16_t>("statistics schema count");
  in.number<std::uint32_t>("statistics channel count");
  in.number<std::uint32_t>("statistics attachment count");
  in.number<std::uint32_t>("statistics metadata count");
  s.chunk_count = in.number<std::uint32_t>("statistics chunk count");
  return s;
}

bool knownCompression(std::string_view c) {
  return c.empty() || c == "zstd" || c == "lz4";
}

/// Refuses a chunk that would decompress to more than is believable.
void checkChunkSizes(const Cursor& at, std::string_view compression, std::uint64_t compressed,
                     std::uint64_t uncompressed) {
  if (!knownCompression(compression)) {
    at.fail(fmt::format("chunk compression '{}' is unknown (none, zstd or lz4)",
                        printable(compression)));
  }
  if (uncompressed > kMaxChunkBytes) {
    at.fail(fmt::format("chunk of {} bytes: damaged (at most {})", uncompressed, kMaxChunkBytes));
  }
  if (compression.empty() && uncompressed != compressed) {
    at.fail(fmt::format("uncompressed chunk says {} bytes and holds {}", uncompressed, compressed));
  }
  if (!compression.empty() && uncompressed > kMaxCompressionRatio * compressed) {
    at.fail(fmt::format("chunk says {} bytes from {} compressed: damaged (at most {} times)",
                        uncompressed, compressed, kMaxCompressionRatio));
  }
}

}  // namespace

struct McapReader::Impl {
  /// A chunk: where its record is, and what its index says of it (if indexed).
  struct Chunk {
    std::uint64_t at = 0;
    std::uint64_t length = 0;  ///< of its content
    std::optional<ChunkIndexFields> index{};
  };

  std::string path;
  std::ifstream file;
  std::uint64_t file_size = 0;
  std::string profile;
  bool indexed = false;
  std::vector<McapSchema> schemas;
  std::vector<McapChannel> channels;
  std::vector<Chunk> chunks;
  std::vector<McapMessageRef> refs;
  std::size_t loaded_chunk = McapMessageRef::kNoChunk;
  std::vector<char> chunk_bytes;
  std::vector<char> scratch;
  std::vector<char> message_bytes;

  explicit Impl(std::string p) : path(std::move(p)) {}

  void open();
  /// Reads `n` bytes at `byte` into `out`, after checking they are in the file.
  void readAt(std::uint64_t byte, std::uint64_t n, std::vector<char>& out, const char* what);
  /// The opcode and content length of the record at `byte`; the content must
  /// end by `end`.
  std::pair<McapOp, std::uint64_t> prefixAt(std::uint64_t byte, std::uint64_t end);
  void readHeader();
  bool readSummary(std::uint64_t summary_start, std::uint64_t summary_offset_start,
                   std::uint32_t summary_crc);
  bool indexChunks(const std::vector<ChunkIndexFields>& indexes, std::uint64_t data_end);
  void indexMessages(std::size_t chunk, const ChunkIndexFields& index);
  void scan();
  void scanRecord(McapOp op, std::uint64_t at, std::span<const char> content);
  void scanChunk(std::size_t chunk);
  void loadChunk(std::size_t chunk);
  void addSchema(McapSchema schema, const Cursor& at);
  void addChannel(McapChannel channel, const Cursor& at);
  void checkReferences() const;
  [[nodiscard]] const McapChannel* channel(std::uint16_t id) const;
};

void McapReader::Impl::readAt(std::uint64_t byte, std::uint64_t n, std::vector<char>& out,
                              const char* what) {
  if (byte > file_size || n > file_size - byte) {
    failAtByte(
        path, byte,
        fmt::format("{} of {} bytes runs past the end of the file ({} bytes)", what, n, file_size));
  }
  out.resize(static_cast<std::size_t>(n));
  file.clear();
  file.seekg(static_cast<std::streamoff>(byte));
  if (n > 0 && !file.read(out.data(), static_cast<std::streamsize>(n))) {
    failAtByte(path, byte, fmt::format("cannot read {} bytes: {}", n, std::strerror(errno)));
  }
}

std::pair<McapOp, std::uint64_t> McapReader::Impl::prefixAt(std::uint64_t byte, std::uint64_t end) {
  readAt(byte, kRecordPrefixBytes, scratch, "record");
  Cursor in(scratch, path, byte);
  const auto op = static_cast<McapOp>(in.number<std::uint8_t>("record opcode"));
  const auto length = in.number<std::uint64_t>("record length");
  if (length > end - byte - kRecordPrefixBytes) {
    failAtByte(
        path, byte,
        fmt::format("record (opcode {:#04x}) of {} bytes runs past byte {}, where its section "
                    "ends",
                    static_cast<int>(op), length, end));
  }
  return {op, length};
}

void McapReader::Impl::open() {
  requireFile(path);
  file.open(path, std::ios::binary);
  if (!file) throw FileError({path}, std::string("cannot open: ") + std::strerror(errno));
  file.seekg(0, std::ios::end);
  file_size = static_cast<std::uint64_t>(file.tellg());
  std::vector<char> bytes;
  readAt(0, std::min<std::uint64_t>(file_size, kMcapMagic.size()), bytes, "magic");
  const std::string_view start(bytes.data(), bytes.size());
  if (start != std::string_view(kMcapMagic.data(), kMcapMagic.size())) {
    if (start.starts_with("\x89MCAP") && start.size() > 5) {
      failAtByte(path, 5,
                 fmt::format("MCAP major version '{}' is not read, only '0'",
                             printable(start.substr(5, 1))));
    }
    failAtByte(path, 0, "not an MCAP file: it does not begin with MCAP's magic");
  }
  if (file_size < kMcapMagic.size() + kRecordPrefixBytes + kMcapTailBytes) {
    failAtByte(path, file_size,
               "truncated: too short to hold a header, a footer and the closing magic");
  }
  readAt(file_size - kMcapMagic.size(), kMcapMagic.size(), bytes, "closing magic");
  if (!std::equal(bytes.begin(), bytes.end(), kMcapMagic.begin())) {
    failAtByte(path, file_size - kMcapMagic.size(),
               "truncated or damaged: the file does not end with MCAP's magic (the recording may "
               "have been interrupted; `mcap recover` rebuilds such a file)");
  }
  readHeader();
  const std::uint64_t footer_at = file_size - kMcapTailBytes;
  const auto [op, length] = prefixAt(footer_at, file_size);
  if (op != McapOp::footer || length != detail::kFooterContentBytes) {
    failAtByte(path, footer_at, "no footer record before the closing magic");
  }
  readAt(footer_at + kRecordPrefixBytes, length, bytes, "footer");
  Cursor footer(bytes, path, footer_at + kRecordPrefixBytes);
  const auto summary_start = footer.number<std::uint64_t>("summary start");
  const auto summary_offset_start = footer.number<std::uint64_t>("summary offset start");
  const auto summary_crc = footer.number<std::uint32_t>("summary crc");
  indexed = summary_start != 0 && readSummary(summary_start, summary_offset_start, summary_crc);
  if (!indexed) {  // no summary, or one whose indexes do not list every message
    chunks.clear();
    refs.clear();
    scan();
  }
  checkReferences();
}

void McapReader::Impl::readHeader() {
  const std::uint64_t at = kMcapMagic.size();
  const auto [op, length] = prefixAt(at, file_size - kMcapTailBytes);
  if (op != McapOp::header) failAtByte(path, at, "the first record is not the header");
  std::vector<char> content;
  readAt(at + kRecordPrefixBytes, length, content, "header");
  Cursor in(content, path, at + kRecordPrefixBytes);
  profile = in.string("header profile");
  in.string("header library");
}

void McapReader::Impl::addSchema(McapSchema schema, const Cursor& at) {
  for (const McapSchema& s : schemas) {
    if (s.id != schema.id) continue;
    if (s.name != schema.name || s.encoding != schema.encoding || s.data != schema.data) {
      at.fail(fmt::format("schema {} defined again differently ('{}', then '{}')", s.id,
                          printable(s.name), printable(schema.name)));
    }
    return;
  }
  schemas.push_back(std::move(schema));
}

void McapReader::Impl::addChannel(McapChannel channel, const Cursor& at) {
  if (const McapChannel* c = this->channel(channel.id)) {
    if (c->topic != channel.topic || c->schema_id != channel.schema_id ||
        c->message_encoding != channel.message_encoding) {
      at.fail(fmt::format("channel {} defined again differently ('{}', then '{}')", c->id,
                          printable(c->topic), printable(channel.topic)));
    }
    return;
  }
  channels.push_back(std::move(channel));
}

const McapChannel* McapReader::Impl::channel(std::uint16_t id) const {
  const auto found = std::find_if(channels.begin(), channels.end(),
                                  [&](const McapChannel& c) { return c.id == id; });
  return found == channels.end() ? nullptr : &*found;
}

void McapReader::Impl::checkReferences() const {
  for (const McapChannel& c : channels) {
    const bool known =
        c.schema_id == 0 || std::any_of(schemas.begin(), schemas.end(),
                                        [&](const McapSchema& s) { return s.id == c.schema_id; });
    if (!known) {
      throw FileError({path}, fmt::format("channel {} ('{}') has schema {}, which the file never "
                                          "defines",
                                          c.id, printable(c.topic), c.schema_id));
    }
  }
  for (const McapMessageRef& m : refs) {
    if (channel(m.channel_id) == nullptr) {
      throw FileError({path}, fmt::format("a message on channel {}, which the file never defines",
                                          m.channel_id));
    }
  }
}

// ---- through the summary ----

bool McapReader::Impl::readSummary(std::uint64_t summary_start, std::uint64_t summary_offset_start,
                                   std::uint32_t summary_crc) {
  const std::uint64_t footer_at = file_size - kMcapTailBytes;
  const std::uint64_t data_start = kMcapMagic.size();
  if (summary_start <= data_start || summary_start > footer_at) {
    failAtByte(
        path, footer_at + kRecordPrefixBytes,
        fmt::format("footer: summary start {} is outside the file's records", summary_start));
  }
  if (summary_offset_start != 0 &&
      (summary_offset_start < summary_start || summary_offset_start > footer_at)) {
    failAtByte(path, footer_at + kRecordPrefixBytes + 8,
               fmt::format("footer: summary offset start {} is outside the summary",
                           summary_offset_start));
  }
  std::vector<char> summary;
  // The summary, then the footer up to its crc: what the crc covers.
  readAt(summary_start, footer_at + kRecordPrefixBytes + 16 - summary_start, summary, "summary");
  if (summary_crc != 0) {
    detail::Crc32 crc;
    crc.add(summary);
    if (crc.value() != summary_crc) {
      failAtByte(path, summary_start,
                 fmt::format("summary crc {:#010x}, the footer says {:#010x}: damaged", crc.value(),
                             summary_crc));
    }
  }
  const std::uint64_t end = summary_offset_start != 0 ? summary_offset_start : footer_at;
  Cursor in(std::span<const char>(summary).first(end - summary_start), path, summary_start);
  std::optional<Statistics> statistics;
  std::vector<ChunkIndexFields> chunk_indexes;
  while (const auto r = nextRecord(in)) {
    const Cursor content(r->content, path, r->at + kRecordPrefixBytes);
    if (r->op == McapOp::schema) addSchema(parseSchema(content), content);
    if (r->op == McapOp::channel) addChannel(parseChannel(content), content);
    if (r->op == McapOp::statistics) statistics = parseStatistics(content);
    if (r->op == McapOp::chunk_index) chunk_indexes.push_back(parseChunkIndex(content, r->at));
  }
  // Without statistics, or with messages outside the chunks, the indexes do not list them all.
  if (!statistics || statistics->chunk_count != chunk_indexes.size()) return false;
  return indexChunks(chunk_indexes, summary_start) && refs.size() == statistics->message_count;
}

bool McapReader::Impl::indexChunks(const std::vector<ChunkIndexFields>& indexes,
                                   std::uint64_t data_end) {
  for (const ChunkIndexFields& c : indexes) {
    std::vector<char> none;
    const Cursor at(none, path, c.at);
    if (c.chunk_start <= kMcapMagic.size() || c.chunk_start > data_end ||
        c.chunk_length < kRecordPrefixBytes || c.chunk_length > data_end - c.chunk_start) {
      at.fail(fmt::format("chunk index: a chunk of {} bytes at byte {} is outside the data section",
                          c.chunk_length, c.chunk_start));
    }
    if (c.message_index_length > data_end - c.chunk_start - c.chunk_length) {
      at.fail(fmt::format("chunk index: message indexes of {} bytes run past the data section",
                          c.message_index_length));
    }
    if (c.compressed_size > c.chunk_length) {
      at.fail(fmt::format("chunk index: {} compressed bytes in a chunk of {}", c.compressed_size,
                          c.chunk_length));
    }
    checkChunkSizes(at, c.compression, c.compressed_size, c.uncompressed_size);
    if (c.message_index_length == 0) return false;  // no message indexes: scan
    chunks.push_back({c.chunk_start, c.chunk_length - kRecordPrefixBytes, c});
    indexMessages(chunks.size() - 1, c);
  }
  std::stable_sort(refs.begin(), refs.end(), [](const McapMessageRef& a, const McapMessageRef& b) {
    return a.chunk != b.chunk ? a.chunk < b.chunk : a.offset < b.offset;
  });
  return true;
}

void McapReader::Impl::indexMessages(std::size_t chunk, const ChunkIndexFields& index) {
  const std::uint64_t at = index.chunk_start + index.chunk_length;
  std::vector<char> bytes;
  readAt(at, index.message_index_length, bytes, "message indexes");
  Cursor in(bytes, path, at);
  while (const auto r = nextRecord(in)) {
    Cursor content(r->content, path, r->at + kRecordPrefixBytes);
    if (r->op != McapOp::message_index) {
      content.failAt(r->at, fmt::format("record opcode {:#04x} among a chunk's message indexes",
                                        static_cast<int>(r->op)));
    }
    const auto channel = content.number<std::uint16_t>("message index channel id");
    Cursor entries = content.group("message index records");
    if (entries.left() % 16 != 0) entries.fail("message index records are not 16-byte entries");
    while (entries.left() > 0) {
      const auto log_time = entries.number<std::uint64_t>("message index log time");
      const auto offset = entries.number<std::uint64_t>("message index offset");
      if (offset >= index.uncompressed_size) {
        entries.fail(fmt::format("message at byte {} of a chunk of {} bytes", offset,
                                 index.uncompressed_size));
      }
      refs.push_back({channel, log_time, chunk, offset});
    }
  }
}

// ---- by scanning ----

void McapReader::Impl::scan() {
  const std::uint64_t footer_at = file_size - kMcapTailBytes;
  detail::Crc32 crc;
  std::vector<char> record;
  std::uint64_t at = 0;
  readAt(0, kMcapMagic.size(), record, "magic");
  crc.add(record);
  at = kMcapMagic.size();
  while (at < footer_at) {
    const auto [op, length] = prefixAt(at, footer_at);
    readAt(at, kRecordPrefixBytes + length, record, "record");
    const std::span<const char> content = std::span<const char>(record).subspan(kRecordPrefixBytes);
    if (op == McapOp::data_end) {
      Cursor in(content, path, at + kRecordPrefixBytes);
      const auto expected = in.number<std::uint32_t>("data section crc");
      if (expected != 0 && expected != crc.value()) {
        failAtByte(path, at,
                   fmt::format("data section crc {:#010x}, its end says {:#010x}: damaged",
                               crc.value(), expected));
      }
      return;  // the summary follows, if any
    }
    crc.add(record);
    scanRecord(op, at, content);
    at += kRecordPrefixBytes + length;
  }
}

void McapReader::Impl::scanRecord(McapOp op, std::uint64_t at, std::span<const char> content) {
  const Cursor in(content, path, at + kRecordPrefixBytes);
  switch (op) {
    case McapOp::header:
      if (at != kMcapMagic.size()) failAtByte(path, at, "a second header record");
      break;
    case McapOp::footer:
      failAtByte(path, at, "a footer record inside the data section");
    case McapOp::schema:
      addSchema(parseSchema(in), in);
      break;
    case McapOp::channel:
      addChannel(parseChannel(in), in);
      break;
    case McapOp::message: {
      const McapMessage m = parseMessage(in);
      refs.push_back({m.channel_id, m.log_time, McapMessageRef::kNoChunk, at});
      break;
    }
    case McapOp::chunk:
      chunks.push_back({at, content.size(), std::nullopt});
      scanChunk(chunks.size() - 1);
      break;
    default:
      break;  // indexes, attachments, metadata, and opcodes of later versions: not needed
  }
}

void McapReader::Impl::scanChunk(std::size_t chunk) {
  loadChunk(chunk);
  Cursor in(chunk_bytes, path, 0, chunks[chunk].at);
  while (const auto r = nextRecord(in)) {
    const Cursor content(r->content, path, r->at + kRecordPrefixBytes, chunks[chunk].at);
    switch (r->op) {
      case McapOp::schema:
        addSchema(parseSchema(content), content);
        break;
      case McapOp::channel:
        addChannel(parseChannel(content), content);
        break;
      case McapOp::message: {
        const McapMessage m = parseMessage(content);
        refs.push_back({m.channel_id, m.log_time, chunk, r->at});
        break;
      }
      default:
        content.failAt(r->at, fmt::format("record opcode {:#04x} inside a chunk (only schemas, "
                                          "channels and messages)",
                                          static_cast<int>(r->op)));
    }
  }
}

// ---- chunks and messages ----

void McapReader::Impl::loadChunk(std::size_t index) {
  if (loaded_chunk == index) return;
  loaded_chunk = McapMessageRef::kNoChunk;
  const Chunk& chunk = chunks[index];
  if (chunk.index) {  // the index said where it is: check a chunk is there
    const auto [op, length] = prefixAt(chunk.at, file_size - kMcapTailBytes);
    if (op != McapOp::chunk || length != chunk.length) {
      failAtByte(path, chunk.at, "the chunk index points at no chunk of its length");
    }
  }
  std::vector<char> record;
  readAt(chunk.at + kRecordPrefixBytes, chunk.length, record, "chunk");
  const Cursor in(record, path, chunk.at + kRecordPrefixBytes);
  const ChunkFields c = parseChunk(in);
  checkChunkSizes(in, c.compression, c.records.size(), c.uncompressed_size);
  if (chunk.index && (chunk.index->compression != c.compression ||
                      chunk.index->compressed_size != c.records.size() ||
                      chunk.index->uncompressed_size != c.uncompressed_size)) {
    failAtByte(path, chunk.at, "the chunk disagrees with its index on its compression or sizes");
  }
  const auto fail = [&](const std::string& what) {
    failAtByte(path, chunk.at,
               fmt::format("chunk ({}): {}", c.compression.empty() ? "none" : c.compression, what));
  };
  if (c.compression.empty()) {
    chunk_bytes.assign(c.records.begin(), c.records.end());
  } else if (c.compression == "zstd") {
    detail::decompressZstd(c.records, c.uncompressed_size, chunk_bytes, fail);
  } else {
    detail::decompressLz4(c.records, c.uncompressed_size, chunk_bytes, fail);
  }
  if (c.uncompressed_crc != 0) {
    detail::Crc32 crc;
    crc.add(chunk_bytes);
    if (crc.value() != c.uncompressed_crc) {
      fail(fmt::format("content crc {:#010x}, the chunk says {:#010x}: damaged", crc.value(),
                       c.uncompressed_crc));
    }
  }
  loaded_chunk = index;
}

McapReader::McapReader(std::string path) : impl_(std::make_unique<Impl>(std::move(path))) {
  impl_->open();
}

McapReader::~McapReader() = default;
McapReader::McapReader(McapReader&&) noexcept = default;
McapReader& McapReader::operator=(McapReader&&) noexcept = default;

const std::string& McapReader::path() const {
  return impl_->path;
}
const std::string& McapReader::profile() const {
  return impl_->profile;
}
bool McapReader::indexed() const {
  return impl_->indexed;
}
const std::vector<McapSchema>& McapReader::schemas() const {
  return impl_->schemas;
}
const std::vector<McapChannel>& McapReader::channels() const {
  return impl_->channels;
}

const McapSchema* McapReader::schemaOf(const McapChannel& channel) const {
  for (const McapSchema& s : impl_->schemas) {
    if (s.id == channel.schema_id) return &s;
  }
  return nullptr;
}

std::vector<McapMessageRef> McapReader::messages(const std::vector<std::uint16_t>& keep) const {
  std::vector<McapMessageRef> out;
  for (const McapMessageRef& m : impl_->refs) {
    if (keep.empty() || std::find(keep.begin(), keep.end(), m.channel_id) != keep.end()) {
      out.push_back(m);
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const McapMessageRef& a, const McapMessageRef& b) {
    return a.log_time < b.log_time;
  });
  return out;
}

McapMessage McapReader::read(const McapMessageRef& ref) {
  Impl& m = *impl_;
  std::optional<Cursor> in;
  if (ref.chunk == McapMessageRef::kNoChunk) {
    const auto [op, length] = m.prefixAt(ref.offset, m.file_size - kMcapTailBytes);
    m.readAt(ref.offset, kRecordPrefixBytes + length, m.message_bytes, "message");
    if (op != McapOp::message) failAtByte(m.path, ref.offset, "no message record here");
    in.emplace(m.message_bytes, m.path, ref.offset);
  } else {
    if (ref.chunk >= m.chunks.size()) throw core::Error("McapReader::read: no such chunk");
    m.loadChunk(ref.chunk);
    const std::span<const char> content(m.chunk_bytes);
    if (ref.offset >= content.size()) failAtByte(m.path, m.chunks[ref.chunk].at, "no such message");
    in.emplace(content.subspan(static_cast<std::size_t>(ref.offset)), m.path, ref.offset,
               m.chunks[ref.chunk].at);
  }
  const auto record = nextRecord(*in);
  const Cursor content(
      record->content, m.path, record->at + kRecordPrefixBytes,
      ref.chunk == McapMessageRef::kNoChunk ? std::nullopt : std::optional(m.chunks[ref.chunk].at));
  if (record->op != McapOp::message) content.failAt(record->at, "the index points at no message");
  const McapMessage message = parseMessage(content);
  if (message.channel_id != ref.channel_id || message.log_time != ref.log_time) {
    content.failAt(record->at, "the message disagrees with its index on its channel or time");
  }
  return message;
}

}  // namespace dcl::io
