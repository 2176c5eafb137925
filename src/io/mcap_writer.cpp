// The MCAP writer: a chunk collects the schema and channel records its
// messages need and the messages themselves; when it reaches the chunk size it
// is compressed and written with one message index per channel. At close the
// data section ends (with its CRC), and the summary repeats the schemas and
// channels, gives the statistics and the chunk indexes, and the summary
// offsets point at each group, as MCAP's own writers lay them out.
#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>

#include <fmt/format.h>
#include <lz4frame.h>
#include <zstd.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/mcap.hpp>

#include "mcap_format.hpp"

namespace dcl::io {

namespace detail {

namespace {

constexpr std::array<std::uint32_t, 256> crcTable() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) != 0 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    table[i] = c;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = crcTable();

}  // namespace

void Crc32::add(std::span<const char> bytes) {
  for (const char b : bytes) {
    state_ = kCrcTable[(state_ ^ static_cast<std::uint8_t>(b)) & 0xFFu] ^ (state_ >> 8);
  }
}

std::vector<char> mcapRecord(McapOp op, const std::vector<char>& content) {
  McapBytes r;
  r.put(static_cast<std::uint8_t>(op)).put(static_cast<std::uint64_t>(content.size()));
  r.putRaw(content);
  return std::move(r.bytes);
}

}  // namespace detail

std::string_view toString(McapCompression compression) {
  switch (compression) {
    case McapCompression::zstd:
      return "zstd";
    case McapCompression::lz4:
      return "lz4";
    default:
      return "";
  }
}

namespace {

using detail::McapBytes;
using detail::McapOp;
using detail::mcapRecord;

std::vector<char> schemaRecord(const McapSchema& s) {
  McapBytes b;
  b.put(s.id).putString(s.name).putString(s.encoding).putString(s.data);
  return mcapRecord(McapOp::schema, b.bytes);
}

std::vector<char> channelRecord(const McapChannel& c) {
  McapBytes metadata;
  for (const auto& [key, value] : c.metadata) metadata.putString(key).putString(value);
  McapBytes b;
  b.put(c.id).put(c.schema_id).putString(c.topic).putString(c.message_encoding);
  b.put(static_cast<std::uint32_t>(metadata.bytes.size())).putRaw(metadata.bytes);
  return mcapRecord(McapOp::channel, b.bytes);
}

std::vector<char> compressed(McapCompression compression, const std::vector<char>& content) {
  std::vector<char> out;
  if (compression == McapCompression::zstd) {
    out.resize(ZSTD_compressBound(content.size()));
    const std::size_t n =
        ZSTD_compress(out.data(), out.size(), content.data(), content.size(), ZSTD_CLEVEL_DEFAULT);
    if (ZSTD_isError(n)) throw core::Error(std::string("zstd: ") + ZSTD_getErrorName(n));
    out.resize(n);
  } else {
    LZ4F_preferences_t preferences{};
    preferences.frameInfo.contentSize = content.size();
    out.resize(LZ4F_compressFrameBound(content.size(), &preferences));
    const std::size_t n =
        LZ4F_compressFrame(out.data(), out.size(), content.data(), content.size(), &preferences);
    if (LZ4F_isError(n)) throw core::Error(std::string("lz4: ") + LZ4F_getErrorName(n));
    out.resize(n);
  }
  return out;
}

/// A chunk index's fields, kept for the summary.
struct ChunkIndex {
  std::uint64_t start_time = 0;
  std::uint64_t end_time = 0;
  std::uint64_t chunk_start = 0;
  std::uint64_t chunk_length = 0;
  std::map<std::uint16_t, std::uint64_t> message_index_offsets{};
  std::uint64_t message_index_length = 0;
  std::uint64_t compressed_size = 0;
  std::uint64_t uncompressed_size = 0;
};

/// The chunk being filled.
struct OpenChunk {
  McapBytes content;
  std::uint64_t start_time = ~std::uint64_t{0};
  std::uint64_t end_time = 0;
  std::size_t messages = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> index{};
};

}  // namespace

struct McapWriter::Impl {
  std::string path;
  McapWriteOptions options;
  TempFile tmp;
  std::ofstream out;
  std::uint64_t position = 0;
  detail::Crc32 data_crc;
  std::vector<McapSchema> schemas;
  std::vector<McapChannel> channels;
  std::vector<bool> schema_written;   ///< in the current chunk (or the data section)
  std::vector<bool> channel_written;  ///< in the current chunk (or the data section)
  std::vector<std::uint32_t> sequence;
  std::vector<std::uint64_t> channel_messages;
  OpenChunk chunk;
  std::vector<ChunkIndex> chunk_indexes;
  std::uint64_t message_count = 0;
  std::uint64_t start_time = ~std::uint64_t{0};
  std::uint64_t end_time = 0;
  bool closed = false;

  Impl(std::string p, McapWriteOptions o)
      : path(std::move(p)), options(std::move(o)), tmp(path), out(tmp.path(), std::ios::binary) {
    if (!out) throw core::FileError({path}, std::string("cannot create: ") + std::strerror(errno));
  }

  /// Writes `bytes`; in the data section they count in its CRC.
  void emit(std::span<const char> bytes, detail::Crc32* crc) {
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) throw core::FileError({path}, std::string("cannot write: ") + std::strerror(errno));
    if (crc != nullptr) crc->add(bytes);
    position += bytes.size();
  }
  void emitData(std::span<const char> bytes) { emit(bytes, &data_crc); }

  void start();
  void require(std::uint16_t channel_id);
  void flushChunk();
  void writeMessageIndexes(ChunkIndex& index);
  void finish();
  std::uint64_t writeSummaryGroup(McapOp op, const std::vector<std::vector<char>>& records,
                                  detail::Crc32& crc, McapBytes& offsets);
};

void McapWriter::Impl::start() {
  emitData(detail::kMcapMagic);
  McapBytes header;
  header.putString(options.profile).putString(options.library);
  emitData(mcapRecord(McapOp::header, header.bytes));
}

/// Puts the schema and channel records `channel_id` needs before its first
/// message in the current chunk (or in the data section, unchunked).
void McapWriter::Impl::require(std::uint16_t channel_id) {
  const McapChannel& c = channels[channel_id - 1];
  auto put = [&](const std::vector<char>& record) {
    if (options.chunked) {
      chunk.content.putRaw(record);
    } else {
      emitData(record);
    }
  };
  if (c.schema_id != 0 && !schema_written[c.schema_id - 1]) {
    put(schemaRecord(schemas[c.schema_id - 1]));
    schema_written[c.schema_id - 1] = true;
  }
  if (!channel_written[c.id - 1]) {
    put(channelRecord(c));
    channel_written[c.id - 1] = true;
  }
}

void McapWriter::Impl::flushChunk() {
  if (chunk.messages == 0) return;
  const std::vector<char>& content = chunk.content.bytes;
  detail::Crc32 crc;
  crc.add(content);
  const std::vector<char> records = options.compression == McapCompression::none
                                        ? content
                                        : compressed(options.compression, content);
  McapBytes b;
  b.put(chunk.start_time).put(chunk.end_time).put(static_cast<std::uint64_t>(content.size()));
  b.put(crc.value()).putString(toString(options.compression));
  b.put(static_cast<std::uint64_t>(records.size())).putRaw(records);
  ChunkIndex index{.start_time = chunk.start_time,
                   .end_time = chunk.end_time,
                   .chunk_start = position,
                   .compressed_size = records.size(),
                   .uncompressed_size = content.size()};
  emitData(mcapRecord(McapOp::chunk, b.bytes));
  index.chunk_length = position - index.chunk_start;
  writeMessageIndexes(index);
  chunk_indexes.push_back(std::move(index));
  chunk = {};
  std::fill(schema_written.begin(), schema_written.end(), false);  // each chunk stands alone
  std::fill(channel_written.begin(), channel_written.end(), false);
}

void McapWriter::Impl::writeMessageIndexes(ChunkIndex& index) {
  const std::uint64_t start = position;
  for (const auto& [channel, entries] : chunk.index) {
    McapBytes b;
    b.put(channel).put(static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, offset] : entries) b.put(time).put(offset);
    index.message_index_offsets[channel] = position;
    emitData(mcapRecord(McapOp::message_index, b.bytes));
  }
  index.message_index_length = position - start;
}

std::uint64_t McapWriter::Impl::writeSummaryGroup(McapOp op,
                                                  const std::vector<std::vector<char>>& records,
                                                  detail::Crc32& crc, McapBytes& offsets) {
  const std::uint64_t start = position;
  for (const auto& r : records) emit(r, &crc);
  if (position > start) {
    McapBytes o;
    o.put(static_cast<std::uint8_t>(op)).put(start).put(position - start);
    offsets.putRaw(mcapRecord(McapOp::summary_offset, o.bytes));
  }
  return position - start;
}

void McapWriter::Impl::finish() {
  flushChunk();
  McapBytes data_end;
  data_end.put(data_crc.value());
  emit(mcapRecord(McapOp::data_end, data_end.bytes), nullptr);
  const std::uint64_t summary_start = position;
  detail::Crc32 crc;
  McapBytes offsets;
  if (options.summary) {
    std::vector<std::vector<char>> records;
    for (const auto& s : schemas) records.push_back(schemaRecord(s));
    writeSummaryGroup(McapOp::schema, records, crc, offsets);
    records.clear();
    for (const auto& c : channels) records.push_back(channelRecord(c));
    writeSummaryGroup(McapOp::channel, records, crc, offsets);
    McapBytes stats;
    stats.put(message_count).put(static_cast<std::uint16_t>(schemas.size()));
    stats.put(static_cast<std::uint32_t>(channels.size()))
        .put(std::uint32_t{0})
        .put(std::uint32_t{0});
    stats.put(static_cast<std::uint32_t>(chunk_indexes.size()));
    stats.put(message_count == 0 ? std::uint64_t{0} : start_time).put(end_time);
    McapBytes counts;
    for (std::size_t i = 0; i < channels.size(); ++i) {
      counts.put(channels[i].id).put(channel_messages[i]);
    }
    stats.put(static_cast<std::uint32_t>(counts.bytes.size())).putRaw(counts.bytes);
    writeSummaryGroup(McapOp::statistics, {mcapRecord(McapOp::statistics, stats.bytes)}, crc,
                      offsets);
    records.clear();
    for (const auto& c : chunk_indexes) {
      McapBytes b;
      b.put(c.start_time).put(c.end_time).put(c.chunk_start).put(c.chunk_length);
      b.put(static_cast<std::uint32_t>(c.message_index_offsets.size() * 10));
      for (const auto& [channel, offset] : c.message_index_offsets) b.put(channel).put(offset);
      b.put(c.message_index_length).putString(toString(options.compression));
      b.put(c.compressed_size).put(c.uncompressed_size);
      records.push_back(mcapRecord(McapOp::chunk_index, b.bytes));
    }
    writeSummaryGroup(McapOp::chunk_index, records, crc, offsets);
  }
  const std::uint64_t summary_offset_start = position;
  if (options.summary) emit(offsets.bytes, &crc);
  McapBytes footer;
  footer.put(std::uint8_t{0x02}).put(std::uint64_t{20});
  footer.put(options.summary ? summary_start : 0).put(options.summary ? summary_offset_start : 0);
  crc.add(footer.bytes);
  footer.put(options.summary ? crc.value() : std::uint32_t{0});
  emit(footer.bytes, nullptr);
  emit(detail::kMcapMagic, nullptr);
  out.close();
  if (!out) throw core::FileError({path}, std::string("cannot write: ") + std::strerror(errno));
}

McapWriter::McapWriter(std::string path, McapWriteOptions options)
    : impl_(std::make_unique<Impl>(std::move(path), std::move(options))) {
  impl_->start();
}

McapWriter::~McapWriter() = default;

std::uint16_t McapWriter::addSchema(const std::string& name, const std::string& encoding,
                                    const std::string& data) {
  Impl& m = *impl_;
  if (m.schemas.size() >= 0xFFFF) throw core::Error("McapWriter: too many schemas");
  const auto id = static_cast<std::uint16_t>(m.schemas.size() + 1);
  m.schemas.push_back({id, name, encoding, data});
  m.schema_written.push_back(false);
  return id;
}

std::uint16_t McapWriter::addChannel(std::uint16_t schema_id, const std::string& topic,
                                     const std::string& message_encoding,
                                     const std::map<std::string, std::string>& metadata) {
  Impl& m = *impl_;
  if (schema_id > m.schemas.size()) {
    throw core::Error(fmt::format("McapWriter: no schema {}", schema_id));
  }
  if (m.channels.size() >= 0xFFFF) throw core::Error("McapWriter: too many channels");
  const auto id = static_cast<std::uint16_t>(m.channels.size() + 1);
  m.channels.push_back({id, schema_id, topic, message_encoding, metadata});
  m.channel_written.push_back(false);
  m.sequence.push_back(0);
  m.channel_messages.push_back(0);
  return id;
}

void McapWriter::write(std::uint16_t channel_id, std::uint64_t log_time, std::uint64_t publish_time,
                       std::span<const std::uint8_t> data) {
  Impl& m = *impl_;
  if (channel_id == 0 || channel_id > m.channels.size()) {
    throw core::Error(fmt::format("McapWriter: no channel {}", channel_id));
  }
  m.require(channel_id);
  McapBytes b;
  b.put(channel_id).put(m.sequence[channel_id - 1]++).put(log_time).put(publish_time);
  b.putRaw({reinterpret_cast<const char*>(data.data()), data.size()});
  const std::vector<char> record = mcapRecord(McapOp::message, b.bytes);
  if (m.options.chunked) {
    OpenChunk& c = m.chunk;
    c.index[channel_id].emplace_back(log_time, c.content.bytes.size());
    c.content.putRaw(record);
    c.start_time = std::min(c.start_time, log_time);
    c.end_time = std::max(c.end_time, log_time);
    ++c.messages;
  } else {
    m.emitData(record);
  }
  ++m.message_count;
  ++m.channel_messages[channel_id - 1];
  m.start_time = std::min(m.start_time, log_time);
  m.end_time = std::max(m.end_time, log_time);
  if (m.options.chunked && m.chunk.content.bytes.size() >= m.options.chunk_size) m.flushChunk();
}

void McapWriter::close() {
  if (impl_->closed) return;
  impl_->finish();
  impl_->tmp.commit();
  impl_->closed = true;
}

}  // namespace dcl::io
