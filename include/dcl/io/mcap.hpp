#pragma once

/// MCAP files (https://mcap.dev/spec, major version 0), the container ROS 2
/// bags are written in: schemas, channels and messages, with the message bytes
/// left as they are (dcl::ros decodes ROS 2's CDR).
///
/// The reader checks every length, offset, count and CRC against the file and
/// against fixed ceilings before it allocates or reads, so a damaged or hostile
/// file is a core::FileError naming the file, the byte and what is wrong, never
/// a crash or a runaway. It reads chunked files (uncompressed, zstd or LZ4
/// frames) and unchunked ones; it lists the messages from the summary's chunk
/// and message indexes when the file has them, and otherwise by scanning the
/// data section. The writer writes chunked files with a summary (schemas,
/// channels, statistics, chunk indexes, message indexes and summary offsets).

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace dcl::io {

/// How the chunks of a written MCAP file are compressed.
enum class McapCompression {
  none,  ///< stored as they are
  zstd,  ///< Zstandard, the default of ROS 2 bags
  lz4,   ///< LZ4 frames
};

/// "", "zstd" or "lz4", as MCAP names them in a chunk.
std::string_view toString(McapCompression compression);

/// A schema: the definition of the messages of the channels that use it.
struct McapSchema {
  std::uint16_t id = 0;
  std::string name{};      ///< e.g. "sensor_msgs/msg/PointCloud2"
  std::string encoding{};  ///< e.g. "ros2msg"
  std::string data{};      ///< the definition, e.g. the concatenated .msg files
};

/// A channel: a topic, its message encoding and its schema.
struct McapChannel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;     ///< 0: no schema
  std::string topic{};             ///< e.g. "/points"
  std::string message_encoding{};  ///< e.g. "cdr"
  std::map<std::string, std::string> metadata{};
};

/// Where one message lies in the file.
struct McapMessageRef {
  static constexpr std::size_t kNoChunk = std::numeric_limits<std::size_t>::max();

  std::uint16_t channel_id = 0;
  std::uint64_t log_time = 0;    ///< ns
  std::size_t chunk = kNoChunk;  ///< the chunk holding it, or none (a record of the data section)
  std::uint64_t offset = 0;      ///< of its record, in the chunk's content or in the file
};

/// One message as read: the bytes are valid until the next read.
struct McapMessage {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;      ///< ns
  std::uint64_t publish_time = 0;  ///< ns
  std::span<const std::uint8_t> data{};
};

/// An open MCAP file, its schemas, channels and messages listed.
class McapReader {
 public:
  /// Opens and lists `path`: through its summary when it has a usable one,
  /// else by scanning its data section. Throws core::FileError naming the file
  /// and the byte when it is missing, not MCAP, truncated or damaged.
  explicit McapReader(std::string path);
  ~McapReader();
  McapReader(McapReader&&) noexcept;
  McapReader& operator=(McapReader&&) noexcept;
  McapReader(const McapReader&) = delete;
  McapReader& operator=(const McapReader&) = delete;

  [[nodiscard]] const std::string& path() const;
  /// The header's profile, e.g. "ros2".
  [[nodiscard]] const std::string& profile() const;
  /// Whether the messages were listed from the summary's indexes (not by scanning).
  [[nodiscard]] bool indexed() const;

  /// Every schema and channel, by id.
  [[nodiscard]] const std::vector<McapSchema>& schemas() const;
  [[nodiscard]] const std::vector<McapChannel>& channels() const;
  /// The schema of `channel`; none when it has none (schema id 0).
  [[nodiscard]] const McapSchema* schemaOf(const McapChannel& channel) const;

  /// The messages of the channels whose id `keep` holds (all when empty), in
  /// log-time order (file order among equal times).
  [[nodiscard]] std::vector<McapMessageRef> messages(
      const std::vector<std::uint16_t>& keep = {}) const;

  /// Reads `ref`; throws core::FileError naming the byte when its record is damaged.
  McapMessage read(const McapMessageRef& ref);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// How an MCAP file is written.
struct McapWriteOptions {
  McapCompression compression = McapCompression::zstd;  ///< of the chunks; default zstd
  std::size_t chunk_size = std::size_t{4} << 20;  ///< bytes of messages a chunk collects; 4 MiB
  bool chunked = true;           ///< messages in chunks; off: records straight in the data section
  bool summary = true;           ///< a summary section with its indexes; off: the footer alone
  std::string profile = "ros2";  ///< the header's profile
  std::string library = "dcl-slam";  ///< the header's library
};

/// Writes one MCAP file. Records go to a temporary file beside `path`
/// (io::TempFile); `close` renames it to `path`, so an interrupted write never
/// leaves a part of a file under the final name.
class McapWriter {
 public:
  /// Creates the temporary file (and parent folders); throws core::FileError if it cannot.
  explicit McapWriter(std::string path, McapWriteOptions options = {});
  /// Removes the temporary file if `close` was not called.
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Adds a schema; returns its id (from 1).
  std::uint16_t addSchema(const std::string& name, const std::string& encoding,
                          const std::string& data);
  /// Adds a channel of schema `schema_id` (0: none); returns its id.
  std::uint16_t addChannel(std::uint16_t schema_id, const std::string& topic,
                           const std::string& message_encoding,
                           const std::map<std::string, std::string>& metadata = {});

  /// Writes a message on `channel_id` (times in ns); the sequence number counts per channel.
  void write(std::uint16_t channel_id, std::uint64_t log_time, std::uint64_t publish_time,
             std::span<const std::uint8_t> data);

  /// Writes the last chunk, the summary and the footer and moves the file to
  /// its final name; throws core::FileError on failure.
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::io
