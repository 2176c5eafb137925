#pragma once

/// Point-cloud files by extension (case-insensitive): `.bin` (KITTI Velodyne),
/// `.pcd` and `.ply`. This is what `dcl-slam convert` calls.

#include <optional>
#include <string>

#include <dcl/core/point_cloud.hpp>

namespace dcl::io {

/// The point-cloud file formats known by extension.
enum class CloudFormat {
  kKittiBin,  ///< `.bin`: KITTI Velodyne float32 x y z reflectance
  kPcd,       ///< `.pcd`: Point Cloud Library
  kPly,       ///< `.ply`: Stanford polygon file, vertices only
};

/// The format named by the extension of `path`; none for any other extension.
std::optional<CloudFormat> cloudFormatOf(const std::string& path);

/// How readCloud treats the points it finds.
struct CloudReadOptions {
  bool drop_nan = false;  ///< drop points whose x, y or z is not finite; default keep them
};

/// How writeCloud stores a cloud.
struct CloudWriteOptions {
  bool ascii = false;  ///< text PCD / PLY instead of binary (ignored for `.bin`); default binary
};

/// Reads the cloud at `path` in the format of its extension. Throws
/// core::FileError for an unknown extension or anything the reader rejects.
core::PointCloud readCloud(const std::string& path, const CloudReadOptions& options = {});

/// Writes `cloud` to `path` in the format of its extension (`.bin` keeps only
/// x y z intensity). Throws core::FileError for an unknown extension or a write failure.
void writeCloud(const std::string& path, const core::PointCloud& cloud,
                const CloudWriteOptions& options = {});

}  // namespace dcl::io
