#pragma once

// Private to dcl_io: the typed point fields shared by the PCD, PLY and
// PointCloud2 readers and the PCD and PLY writers. A reader describes where
// each channel lives in its records (`PointLayout`); the functions here check
// bounds and turn bytes or text tokens into a core::PointCloud.

#include <array>
#include <bit>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/io/file.hpp>

namespace dcl::io::detail {

static_assert(std::endian::native == std::endian::little,
              "dcl::io reads and writes little-endian data by memcpy");

/// How the bits of a scalar are read.
enum class ScalarKind : std::uint8_t { kInt, kUint, kFloat };

/// A scalar field type: signed, unsigned or floating point, of 1, 2, 4 or 8 bytes.
struct ScalarType {
  ScalarKind kind = ScalarKind::kFloat;  ///< default: float
  std::size_t size = 4;                  ///< bytes; default 4 (float32)
};

/// True when `type` is a size this code can read (floats: 4 or 8; integers: 1, 2, 4, 8).
bool isValid(ScalarType type);

/// The value of the scalar at `p` (which must hold `type.size` bytes) as a double;
/// `swap` reverses its bytes first (big-endian data).
double loadScalar(const char* p, ScalarType type, bool swap);

/// The token as a value of `type` (integers in range); none if it is not one.
std::optional<double> parseTyped(std::string_view token, ScalarType type);

/// a * b, none on overflow.
std::optional<std::size_t> checkedMul(std::size_t a, std::size_t b);

/// The PointCloud channels a field can feed.
enum class Channel : std::uint8_t { kX, kY, kZ, kIntensity, kTime, kRing };
inline constexpr std::size_t kChannelCount = 6;

/// One value per channel, indexed by Channel.
using ChannelValues = std::array<double, kChannelCount>;

/// The channel a field name feeds: x y z, intensity (or i), time (or t, timestamp), ring.
std::optional<Channel> channelOf(std::string_view name);

/// Where one channel lives. Binary: value i is at base + offset + i * stride.
/// Text: `offset` is the token index and `stride` is unused.
struct FieldSlot {
  std::size_t offset = 0;  ///< bytes from the start of the data (or token index); default 0
  std::size_t stride = 0;  ///< bytes from one point's value to the next; default 0
  ScalarType type{};       ///< default float32
  std::string name{};      ///< the field's name in the file (for messages)
};

/// The channels found in a record layout; x, y and z are required before decoding.
struct PointLayout {
  std::array<std::optional<FieldSlot>, kChannelCount> slots{};  ///< indexed by Channel
  bool swap = false;  ///< true for big-endian data; default little-endian

  [[nodiscard]] const std::optional<FieldSlot>& slot(Channel c) const {
    return slots[static_cast<std::size_t>(c)];
  }
  /// Sets the slot of `c` unless a field already feeds it (the first field wins).
  void assign(Channel c, FieldSlot s);
  /// The first of x, y, z that no field feeds, if any.
  [[nodiscard]] std::optional<std::string> missingXyz() const;
};

/// Bytes from the data start that decoding `n` points of `layout` touches (0 for
/// no points); none if that number overflows.
std::optional<std::size_t> bytesNeeded(const PointLayout& layout, std::size_t n);

/// Times of larger magnitude than this (seconds) are absolute, not offsets in a scan.
inline constexpr double kAbsoluteTimeThreshold = 1e6;

/// Collects decoded points into a core::PointCloud.
class CloudBuilder {
 public:
  CloudBuilder(const PointLayout& layout, bool drop_nan);

  /// Reserves room for `n` points.
  void reserve(std::size_t n);

  /// Adds one point (time in seconds); an error text when a value does not fit its
  /// channel (a ring outside 0..65535 or not an integer).
  std::optional<std::string> add(const ChannelValues& v);

  /// The cloud. Absolute times (any beyond kAbsoluteTimeThreshold) are made relative
  /// to `stamp` when given, else to the earliest point.
  core::PointCloud finish(std::optional<double> stamp);

 private:
  bool drop_nan_;
  bool has_intensity_;
  bool has_time_;
  bool has_ring_;
  core::PointCloud cloud_;
  std::vector<double> times_;
};

/// The values of point `i` of a bounds-checked binary layout (time in seconds:
/// integer time fields count nanoseconds).
ChannelValues loadPoint(const char* base, std::size_t i, const PointLayout& layout);

/// Decodes `n` binary points from `data`, which must hold bytesNeeded(layout, n);
/// errors name `path`, the byte offset `data_offset` and the point.
void decodeBinaryPoints(std::span<const char> data, std::size_t n, const PointLayout& layout,
                        CloudBuilder& builder, const std::string& path, std::size_t data_offset);

/// Reads `n` text lines of `tokens_per_point` values (blank lines skipped) from `in`;
/// `line` is the number of the last line read and advances. Errors name the line.
void readAsciiPoints(ByteReader& in, std::size_t& line, std::size_t n, std::size_t tokens_per_point,
                     const PointLayout& layout, CloudBuilder& builder);

/// A channel a writer stores: PCD / PLY-agnostic name and binary form.
struct OutField {
  Channel channel = Channel::kX;  ///< default x
  const char* name = "x";         ///< field name in the file; default "x"
  ScalarType type{};              ///< float32 (x y z intensity time) or uint16 (ring)
};

/// x y z, then intensity, time and ring when the cloud has them.
std::vector<OutField> outFields(const core::PointCloud& cloud);

/// One text line per point, values in their shortest exact decimal form.
std::string encodeAscii(const core::PointCloud& cloud, const std::vector<OutField>& fields);

/// Little-endian records one after another, or (`by_field`) each field's values
/// one after another.
std::string encodeBinary(const core::PointCloud& cloud, const std::vector<OutField>& fields,
                         bool by_field);

/// Throws FileError naming `path` unless every channel of `cloud` has one value a point.
void requireConsistent(const core::PointCloud& cloud, const std::string& path);

/// Writes `bytes` to `path` atomically (binary mode).
void writeBytes(const std::string& path, const std::string& bytes);

}  // namespace dcl::io::detail
