#pragma once

/// The compact wire encoding of a LiDAR-Iris descriptor (DESIGN.md §4). The
/// paper sends the binary feature images (29.12 kB a keyframe) and the authors'
/// code a float32 per image byte (about 115 kB); everything in a descriptor
/// follows from its 80 x 360 occupancy image, so only the image goes on the
/// wire, zstd-compressed, and the receiver recomputes the row key and the
/// features, bit for bit.
///
/// Layout (little-endian): magic "DI" | version u8 (1) | kind u8 (1 = iris
/// image) | rows u16 | columns u16 | zstd frame of rows*columns bytes (with its
/// content size and checksum). A decoder never trusts it: sizes are checked
/// before anything is allocated, the zstd frame must declare exactly
/// rows*columns bytes and pass its checksum, and nothing may follow it.

#include <cstdint>
#include <span>
#include <vector>

#include <dcl/core/error.hpp>
#include <dcl/place/descriptor.hpp>
#include <dcl/place/lidar_iris.hpp>

namespace dcl::place {

/// Version written in the header; decoders reject any other.
inline constexpr std::uint8_t kIrisCodecVersion = 1;

/// Bytes of the header before the zstd frame.
inline constexpr std::size_t kIrisCodecHeaderBytes = 8;

/// Largest image a decoder accepts (rows * columns), bounding its allocation.
inline constexpr std::size_t kIrisCodecMaxCells = 1024 * 1024;

/// A received encoding could not be decoded; what() says why in one line.
class DecodeError : public core::Error {
 public:
  using core::Error::Error;
};

/// Encoding options.
struct IrisCodecConfig {
  static constexpr int kMaxZstdLevel = 22;  ///< zstd's strongest level (ZSTD_maxCLevel)

  /// zstd level 1..22. On KITTI 00 (mean bytes, encode time a scan): 3: 2998 B,
  /// 0.06 ms; 9: 2699 B, 0.7 ms; 15: 2511 B, 3 ms; 19: 2477 B, 14 ms.
  int zstd_level = 15;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("zstd_level", zstd_level, "zstd level for descriptors on the wire (1..22)")
        .within(1, kMaxZstdLevel);
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const IrisCodecConfig& config);

/// Encodes an occupancy image. Throws core::Error when it is empty or its cell
/// count does not match its dimensions.
std::vector<std::uint8_t> encodeIrisImage(const IrisImage& image,
                                          const IrisCodecConfig& codec = {});

/// Encodes a descriptor's image (the rest is recomputed on receipt).
std::vector<std::uint8_t> encodeIris(const IrisDescriptor& descriptor,
                                     const IrisCodecConfig& codec = {});

/// Decodes an image exactly. Throws DecodeError on a bad magic, version or
/// kind, dimensions over kIrisCodecMaxCells, a truncated or corrupt frame, a
/// size mismatch or trailing bytes.
IrisImage decodeIrisImage(std::span<const std::uint8_t> bytes);

/// Decodes and describes: the same descriptor the sender had, bit for bit.
/// Throws DecodeError as decodeIrisImage does, and also when the image's
/// dimensions do not match `config`.
IrisDescriptor decodeIris(std::span<const std::uint8_t> bytes, const IrisConfig& config = {});

}  // namespace dcl::place
