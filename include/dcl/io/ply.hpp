#pragma once

/// PLY (Stanford polygon) files holding point clouds.
///
/// Reading accepts ascii, binary_little_endian and binary_big_endian, and takes
/// the `vertex` element: x y z (required) and, by name, intensity (or i), time
/// (or t, timestamp) and ring, each of any scalar type (char uchar short ushort
/// int uint float double, or int8 uint8 int16 uint16 int32 uint32 float32
/// float64). CloudCompare's `scalar_` prefix is ignored (`scalar_intensity` is
/// the intensity). Other vertex properties are skipped; other elements (faces,
/// edges, with list properties) are checked and skipped. Time properties of
/// float type are seconds and of integer type nanoseconds; times beyond 1e6 s
/// are absolute and are made relative to the earliest point.

#include <Eigen/Core>
#include <span>
#include <string>

#include <dcl/core/point_cloud.hpp>
#include <dcl/io/image.hpp>

namespace dcl::io {

/// How a PLY reader treats the points it finds.
struct PlyReadOptions {
  bool drop_nan = false;  ///< drop points whose x, y or z is not finite; default keep them
};

/// The encoding of a written PLY file.
enum class PlyEncoding {
  kAscii,               ///< one text line per vertex, shortest exact decimal form
  kBinaryLittleEndian,  ///< little-endian records, one per vertex
};

/// How a PLY writer stores a cloud.
struct PlyWriteOptions {
  PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian;  ///< default binary
};

/// Reads the vertices of a PLY file. Throws core::FileError naming the file and
/// the line (header, ASCII data) or byte offset (binary data), and the element
/// or property when one is to blame.
core::PointCloud readPly(const std::string& path, const PlyReadOptions& options = {});

/// Decodes the content of a PLY file held in memory, as readPly reads one; its
/// errors name `name` (where the bytes came from).
core::PointCloud decodePly(std::span<const char> bytes, const std::string& name,
                           const PlyReadOptions& options = {});

/// Writes `cloud` as the `vertex` element of a PLY file: float x y z, then float
/// intensity, float time (seconds) and ushort ring when present. Throws
/// core::FileError on a write failure or an inconsistent cloud.
void writePly(const std::string& path, const core::PointCloud& cloud,
              const PlyWriteOptions& options = {});

/// Writes points with one colour each (a map coloured by robot) as the
/// `vertex` element of a PLY file: float x y z, then uchar red green blue, the
/// names CloudCompare, MeshLab and Open3D show as colours (readPly reads the
/// points and skips the colours). Throws core::FileError on a write failure or
/// when the two lists differ in length.
void writeColouredPly(const std::string& path, std::span<const Eigen::Vector3f> points,
                      std::span<const Rgb> colours, const PlyWriteOptions& options = {});

}  // namespace dcl::io
