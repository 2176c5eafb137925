#pragma once

// The record layer of a ROS1 bag (format 2.0), read by our own bounded reader:
// every length, offset and size in the file is checked against the file and
// against fixed ceilings before anything is allocated or read, so a corrupt or
// hostile bag is a FileError naming the byte, never a crash or a runaway.
//
// The bag is scanned once from its first record to its last; its index (the
// records after `index_pos`) is not trusted and not needed, so a bag whose
// recording was interrupted before the index was written reads as far as its
// last whole record. Chunks may be uncompressed, bz2 or lz4 (LZ4 frame format,
// as rosbag writes it).

#include <cstdint>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace dcl::io::detail {

/// One connection (a topic with its message type) of a bag.
struct BagConnection {
  std::uint32_t id = 0;
  std::string topic{};
  std::string type{};    ///< e.g. "sensor_msgs/PointCloud2"
  std::string md5sum{};  ///< of the message definition
};

/// Where one message lies in the bag.
struct BagMessage {
  static constexpr std::size_t kNoChunk = std::numeric_limits<std::size_t>::max();

  std::size_t connection = 0;     ///< index into BagFile::connections()
  std::uint64_t time = 0;         ///< record time, nanoseconds since the epoch
  std::size_t chunk = kNoChunk;   ///< the chunk holding it, or none (a top-level record)
  std::uint64_t offset = 0;       ///< of its bytes, in the chunk's content or in the file
  std::uint32_t size = 0;         ///< bytes
  std::uint64_t record_byte = 0;  ///< file offset of its record, or of its chunk
};

/// An open bag, scanned and indexed.
class BagFile {
 public:
  /// Opens and scans `path`. Throws core::FileError naming the file (and the
  /// byte) when it is missing, not a bag, truncated or corrupt.
  explicit BagFile(std::string path);

  [[nodiscard]] const std::string& path() const { return path_; }

  /// Every connection, in order of first appearance.
  [[nodiscard]] const std::vector<BagConnection>& connections() const { return connections_; }

  /// The messages whose connection passes `keep`, in record-time order (file
  /// order among equal times), as rosbag's views deliver them.
  [[nodiscard]] std::vector<BagMessage> messages(
      const std::function<bool(const BagConnection&)>& keep) const;

  /// The serialised bytes of `message`; valid until the next call.
  std::span<const char> read(const BagMessage& message);

 private:
  struct Chunk {
    std::uint64_t data_byte = 0;  ///< file offset of its (compressed) content
    std::uint32_t data_size = 0;  ///< bytes in the file
    std::uint32_t size = 0;       ///< bytes once decompressed
    std::string compression{};    ///< "none", "bz2" or "lz4"
    std::uint64_t record_byte = 0;
  };

  void scan();
  void scanChunk(std::size_t index);
  void addConnection(std::uint32_t id, const std::string& topic, std::span<const char> data,
                     std::uint64_t byte);
  /// Reads `n` bytes at `byte` of the file into `out`.
  void readAt(std::uint64_t byte, std::size_t n, std::vector<char>& out);
  /// Loads (and decompresses) chunk `index` into chunk_bytes_.
  void loadChunk(std::size_t index);

  std::string path_;
  std::ifstream file_;
  std::uint64_t file_size_ = 0;
  static constexpr std::uint64_t kUnknownPosition = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t file_at_ = kUnknownPosition;  ///< where the stream is, to skip needless seeks
  std::vector<BagConnection> connections_;
  std::map<std::uint32_t, std::size_t> connection_index_;
  std::vector<Chunk> chunks_;
  std::vector<BagMessage> messages_;
  /// Connection ids of messages_, resolved once the whole bag is scanned.
  std::vector<std::uint32_t> message_connection_ids_;

  std::size_t loaded_chunk_ = BagMessage::kNoChunk;
  std::vector<char> chunk_bytes_;
  /// bzlib's work memory (3.6 MB for a stream of 900 kB blocks), kept from one
  /// chunk to the next rather than allocated and freed for each.
  class Bz2Memory {
   public:
    static void* allocate(void* self, int count, int size);
    static void release(void* self, void* block);

   private:
    struct Block {
      std::unique_ptr<char[]> bytes;
      std::size_t size = 0;
      bool in_use = false;
    };
    std::vector<Block> blocks_;
  };
  Bz2Memory bz2_memory_;
  std::vector<char> message_bytes_;
};

}  // namespace dcl::io::detail
