#pragma once

/// KITTI Velodyne scans (`.bin`): one record of four little-endian float32
/// (x, y, z, reflectance) per point, nothing else in the file.

#include <span>
#include <string>

#include <dcl/core/point_cloud.hpp>

namespace dcl::io {

/// Bytes of one KITTI point record.
inline constexpr std::size_t kKittiRecordBytes = 16;

/// Reads a KITTI `.bin` scan; reflectance goes to the intensity channel. Throws
/// core::FileError when the file cannot be read, is empty (a scan without points
/// is taken as a failed copy), or its size is not a multiple of 16 bytes (naming
/// the byte offset of the partial record).
core::PointCloud readKittiScan(const std::string& path);

/// Decodes the content of a KITTI `.bin` scan held in memory, as readKittiScan
/// reads one; its errors name `name` (where the bytes came from).
core::PointCloud decodeKittiScan(std::span<const char> bytes, const std::string& name);

/// Writes `cloud` as a KITTI `.bin` scan (intensity 0 when the cloud has none;
/// time and ring are not stored). Throws core::FileError on a write failure, an
/// inconsistent cloud or an empty one (which would not read back).
void writeKittiScan(const std::string& path, const core::PointCloud& cloud);

}  // namespace dcl::io
