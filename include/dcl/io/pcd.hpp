#pragma once

/// PCD (Point Cloud Library) files, version 0.7 (and the 0.5/0.6 headers it
/// extends).
///
/// Reading accepts DATA ascii, binary and binary_compressed (LZF, fields stored
/// one after another), fields of any TYPE/SIZE (F4 F8 U1 U2 U4 U8 I1 I2 I4 I8)
/// and COUNT. Fields map to core::PointCloud channels by name: x y z (required),
/// intensity or i, time or t or timestamp, ring; the first field of a channel
/// wins and every other field is skipped. Time fields of float type are seconds
/// and of integer type nanoseconds; times beyond 1e6 s are absolute and are made
/// relative to the earliest point. A ring must be an integer in 0..65535.

#include <span>
#include <string>

#include <dcl/core/point_cloud.hpp>

namespace dcl::io {

/// How a PCD reader treats the points it finds.
struct PcdReadOptions {
  bool drop_nan = false;  ///< drop points whose x, y or z is not finite; default keep them
};

/// The DATA encoding of a written PCD file.
enum class PcdEncoding {
  kAscii,             ///< one text line per point, shortest exact decimal form
  kBinary,            ///< little-endian records, one per point
  kBinaryCompressed,  ///< LZF-compressed, fields one after another (PCL's compressed form)
};

/// How a PCD writer stores a cloud.
struct PcdWriteOptions {
  PcdEncoding encoding = PcdEncoding::kBinary;  ///< default binary
};

/// Reads a PCD file as an unorganised cloud (WIDTH * HEIGHT points, row by row).
/// Throws core::FileError naming the file and the line (header, ASCII data) or
/// byte offset (binary data), and the field when one is to blame.
core::PointCloud readPcd(const std::string& path, const PcdReadOptions& options = {});

/// Decodes the content of a PCD file held in memory, as readPcd reads one; its
/// errors name `name` (where the bytes came from).
core::PointCloud decodePcd(std::span<const char> bytes, const std::string& name,
                           const PcdReadOptions& options = {});

/// Writes `cloud` as PCD: fields x y z (F4), then intensity (F4), time (F4,
/// seconds) and ring (U2) when present; WIDTH = points, HEIGHT = 1. Throws
/// core::FileError on a write failure or an inconsistent cloud.
void writePcd(const std::string& path, const core::PointCloud& cloud,
              const PcdWriteOptions& options = {});

}  // namespace dcl::io
