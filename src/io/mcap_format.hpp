#pragma once

// MCAP's constants and byte layout (https://mcap.dev/spec), shared by the
// reader and the writer. Private to dcl::io.

#include <array>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace dcl::io::detail {

/// The magic that opens and closes every MCAP file: 0x89 "MCAP" major version '0' "\r\n".
inline constexpr std::array<char, 8> kMcapMagic = {'\x89', 'M', 'C', 'A', 'P', '0', '\r', '\n'};

/// Record opcodes.
enum class McapOp : std::uint8_t {
  header = 0x01,
  footer = 0x02,
  schema = 0x03,
  channel = 0x04,
  message = 0x05,
  chunk = 0x06,
  message_index = 0x07,
  chunk_index = 0x08,
  attachment = 0x09,
  attachment_index = 0x0A,
  statistics = 0x0B,
  metadata = 0x0C,
  metadata_index = 0x0D,
  summary_offset = 0x0E,
  data_end = 0x0F,
};

/// A record: opcode (1 byte) and content length (8 bytes), then the content.
inline constexpr std::uint64_t kRecordPrefixBytes = 9;
/// The footer's content: summary start, summary offset start, summary CRC.
inline constexpr std::uint64_t kFooterContentBytes = 8 + 8 + 4;
/// The footer record and the closing magic: the last bytes of every file.
inline constexpr std::uint64_t kMcapTailBytes =
    kRecordPrefixBytes + kFooterContentBytes + kMcapMagic.size();

/// CRC-32 (ISO-HDLC, zlib's), the checksum of MCAP's chunks, data and summary sections.
class Crc32 {
 public:
  void add(std::span<const char> bytes);
  /// The CRC of every byte added so far.
  [[nodiscard]] std::uint32_t value() const { return ~state_; }

 private:
  std::uint32_t state_ = 0xFFFFFFFFu;
};

/// Appends MCAP's little-endian fields to a byte buffer.
struct McapBytes {
  std::vector<char> bytes;

  template <class T>
  McapBytes& put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    const std::size_t at = bytes.size();
    bytes.resize(at + sizeof(T));
    std::memcpy(bytes.data() + at, &value, sizeof(T));
    return *this;
  }
  /// A string or byte array prefixed by its uint32 length.
  McapBytes& putString(std::string_view s) {
    put(static_cast<std::uint32_t>(s.size()));
    bytes.insert(bytes.end(), s.begin(), s.end());
    return *this;
  }
  McapBytes& putRaw(std::span<const char> raw) {
    bytes.insert(bytes.end(), raw.begin(), raw.end());
    return *this;
  }
};

/// The record of opcode `op` holding `content`.
std::vector<char> mcapRecord(McapOp op, const std::vector<char>& content);

}  // namespace dcl::io::detail
