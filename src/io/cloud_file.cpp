#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/cloud_file.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pcd.hpp>
#include <dcl/io/ply.hpp>

namespace dcl::io {

namespace {

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

CloudFormat requireFormat(const std::string& path) {
  const auto format = cloudFormatOf(path);
  if (!format) {
    throw core::FileError({path}, fmt::format("unknown point-cloud extension '{}' (expected "
                                              ".bin, .pcd or .ply)",
                                              lowerExtension(path)));
  }
  return *format;
}

/// `cloud` without the points whose x, y or z is not finite.
core::PointCloud dropNonFinite(const core::PointCloud& cloud) {
  core::PointCloud out;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!cloud.points[i].allFinite()) continue;
    out.points.push_back(cloud.points[i]);
    if (cloud.hasIntensity()) out.intensity.push_back(cloud.intensity[i]);
    if (cloud.hasTime()) out.time.push_back(cloud.time[i]);
    if (cloud.hasRing()) out.ring.push_back(cloud.ring[i]);
  }
  return out;
}

}  // namespace

std::optional<CloudFormat> cloudFormatOf(const std::string& path) {
  const std::string ext = lowerExtension(path);
  if (ext == ".bin") return CloudFormat::kKittiBin;
  if (ext == ".pcd") return CloudFormat::kPcd;
  if (ext == ".ply") return CloudFormat::kPly;
  return std::nullopt;
}

core::PointCloud readCloud(const std::string& path, const CloudReadOptions& options) {
  switch (requireFormat(path)) {
    case CloudFormat::kKittiBin: {
      core::PointCloud cloud = readKittiScan(path);
      return options.drop_nan ? dropNonFinite(cloud) : cloud;
    }
    case CloudFormat::kPcd:
      return readPcd(path, {options.drop_nan});
    case CloudFormat::kPly:
      break;
  }
  return readPly(path, {options.drop_nan});
}

void writeCloud(const std::string& path, const core::PointCloud& cloud,
                const CloudWriteOptions& options) {
  switch (requireFormat(path)) {
    case CloudFormat::kKittiBin:
      return writeKittiScan(path, cloud);
    case CloudFormat::kPcd:
      return writePcd(path, cloud, {options.ascii ? PcdEncoding::kAscii : PcdEncoding::kBinary});
    case CloudFormat::kPly:
      break;
  }
  writePly(path, cloud, {options.ascii ? PlyEncoding::kAscii : PlyEncoding::kBinaryLittleEndian});
}

}  // namespace dcl::io
