#pragma once

/// The compact verification cloud (DESIGN.md §4): what the querying robot
/// sends with a loop candidate so that the neighbour can verify it (stage 2 of
/// the protocol). The paper sends the filtered scan as float points, about
/// 100 kB a VLP-16 keyframe; here an HDL-64 keyframe takes under 25 kB:
///
/// - voxel-filtered on the grid the verifier uses (VerificationConfig::voxel_size),
///   so the verifier's own filter leaves the received cloud as it is and the
///   registration sees what it would see with the full scan;
/// - each coordinate quantised to a signed 16-bit offset from the keyframe
///   origin, in steps of `resolution` or coarser when the cloud's extent needs
///   it (the step goes in the header), which is far below the voxel size;
/// - points sorted along a Morton (Z-order) curve of the quantised grid, so
///   that consecutive points are neighbours in space, then delta-coded, zigzag
///   mapped and split into byte planes (all low bytes, then all high bytes, per
///   axis): the high planes are nearly all zero and the low ones small, which
///   zstd turns into about 2.7 bytes a point at the defaults (23 kB at most
///   for a KITTI HDL-64 keyframe; its float xyz take 1.5 MB).
///
/// Layout (little-endian): magic "DV" | version u8 (1) | flags u8 (0) |
/// resolution f32 (m) | point count u32 | zstd frame of 6 * count bytes (with
/// its content size and checksum). A decoder never trusts it: the header is
/// checked before anything is allocated, the frame must declare exactly 6 *
/// count bytes and pass its checksum, and nothing may follow it.

#include <cstdint>
#include <span>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/point_cloud.hpp>

namespace dcl::registration {

/// Version written in the header; decoders reject any other.
inline constexpr std::uint8_t kCloudCodecVersion = 1;

/// Bytes of the header before the zstd frame.
inline constexpr std::size_t kCloudCodecHeaderBytes = 12;

/// Most points a decoder accepts, bounding its allocation (6 MB of coordinates).
inline constexpr std::uint32_t kCloudCodecMaxPoints = 1U << 20;

/// Finest and coarsest quantisation steps a decoder accepts (m).
inline constexpr double kCloudCodecMinResolution = 1e-4;
inline constexpr double kCloudCodecMaxResolution = 1.0;

/// A received verification cloud could not be decoded; what() says why in one line.
class CloudDecodeError : public core::Error {
 public:
  using core::Error::Error;
};

/// How the cloud is made compact.
struct CloudCodecConfig {
  static constexpr int kMaxZstdLevel = 22;  ///< zstd's strongest level (ZSTD_maxCLevel)

  /// m, voxel filter before quantisation; 0 sends the points as they are.
  /// Keep it equal to VerificationConfig::voxel_size.
  double voxel_size = 0.6;
  /// m, quantisation step at least (2 cm: errors of at most 1 cm an axis, a
  /// sixtieth of a voxel, averaging out over thousands of pairs); coarser when
  /// the cloud reaches beyond 32767 steps.
  double resolution = 0.02;
  /// m, points farther from the origin are not sent (0: all); LiDAR returns
  /// beyond the submap's reach add bytes and no pairs.
  double max_range = 0.0;
  /// zstd level 1..22. On KITTI 00 (largest message, encode time of a scan):
  /// 3: 23.6 kB, 3.0 ms; 9: 23.4 kB, 3.0 ms; 15: 23.2 kB, 4.5 ms; 19: 23.3 kB, 9 ms.
  int zstd_level = 15;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("voxel_size", voxel_size, "m, voxel filter before quantisation (0: none)")
        .zeroOrWithin(core::kMinVoxelEdge, core::kMaxVoxelEdge, "none");
    v.field("resolution", resolution, "m, finest quantisation step")
        .within(kCloudCodecMinResolution, kCloudCodecMaxResolution);
    v.field("max_range", max_range, "m, farther points are not sent (0: all)").nonNegative();
    v.field("zstd_level", zstd_level, "zstd level for verification clouds (1..22)")
        .within(1, kMaxZstdLevel);
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const CloudCodecConfig& config);

/// Encodes the points of `cloud` (its keyframe frame; other channels are not
/// sent). Non-finite points are dropped. Throws core::Error for an invalid
/// configuration or more than kCloudCodecMaxPoints points after filtering.
std::vector<std::uint8_t> encodeVerificationCloud(const core::PointCloud& cloud,
                                                  const CloudCodecConfig& config = {});

/// Decodes a verification cloud: its points in the sender's keyframe frame,
/// each within half a quantisation step (an axis) of what was encoded. Throws
/// CloudDecodeError on a bad magic, version or flags, an invalid resolution, a
/// count over kCloudCodecMaxPoints, a truncated or corrupt frame, a size
/// mismatch or trailing bytes; never anything else.
core::PointCloud decodeVerificationCloud(std::span<const std::uint8_t> bytes);

}  // namespace dcl::registration
