#pragma once

/// Trajectory files: KITTI odometry poses (with an optional times file), TUM
/// `t x y z qx qy qz qw` files, and the KITTI `calib.txt` of a sequence.
///
/// Readers raise core::FileError naming the file, the line, the field and what
/// was wrong; writers write atomically and with full round-trip precision
/// (shortest decimal that reads back to the same double).
///
/// KITTI rotations are printed with 7 significant digits, so the 3x3 block read
/// back is orthonormal only to about 1e-7. The reader keeps the 3x4 matrix as
/// written, as evo and the KITTI devkit do, so that every metric computed on it
/// matches theirs; a consumer that needs an exact rotation projects it with
/// core::projectToSO3. A 3x3 block further than 1e-2 (Frobenius norm of
/// R^T R - I) from a rotation, or a reflection, is rejected as corrupt.

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/core/trajectory.hpp>

namespace dcl::io {

/// The text trajectory formats the `convert` and `eval` commands understand.
enum class PoseFormat {
  kitti,  ///< 12 numbers a line: the row-major 3x4 matrix T_world_cam; stamps in a side file
  tum,    ///< `t x y z qx qy qz qw` a line; '#' comments and blank lines allowed
};

/// "kitti" or "tum" (lower case). Throws core::Error naming the accepted values otherwise.
PoseFormat parsePoseFormat(std::string_view name);

/// "kitti" or "tum".
std::string_view toString(PoseFormat format);

/// Reads a KITTI times file: one stamp a line (s), blank lines skipped. Throws
/// core::FileError naming the file, the line and what is wrong: not one finite
/// number, a stamp not after the one before it (stamps strictly increase), or
/// no stamp at all.
std::vector<double> readKittiTimes(const std::string& path);

/// Reads a KITTI pose file. With `times_path`, stamps come from that file
/// (readKittiTimes; its count must match the poses, else core::FileError naming
/// both files); without it, the stamp of pose i is its index i (0, 1, 2, ...).
/// Blank lines are skipped; an empty file is an error.
core::Trajectory readKittiPoses(const std::string& path,
                                const std::optional<std::string>& times_path = std::nullopt);

/// Reads a TUM trajectory: `t x y z qx qy qz qw` a line, '#' comments and blank
/// lines allowed. Quaternions are normalised; one whose norm is not within 1e-2
/// of 1 is rejected as corrupt. A file without poses is an error.
core::Trajectory readTumPoses(const std::string& path);

/// Writes `trajectory` as KITTI poses (3x4 row-major) and, with `times_path`,
/// its stamps one a line. Both files are written atomically.
void writeKittiPoses(const std::string& path, const core::Trajectory& trajectory,
                     const std::optional<std::string>& times_path = std::nullopt);

/// Writes `trajectory` as a TUM file (quaternion with qw >= 0), atomically.
void writeTumPoses(const std::string& path, const core::Trajectory& trajectory);

/// Reads `path` in `format`; `times_path` is only meaningful for KITTI (a TUM
/// file carries its stamps: passing one throws core::Error).
core::Trajectory readPoses(const std::string& path, PoseFormat format,
                           const std::optional<std::string>& times_path = std::nullopt);

/// Writes `trajectory` to `path` in `format`; `times_path` as for readPoses.
void writePoses(const std::string& path, PoseFormat format, const core::Trajectory& trajectory,
                const std::optional<std::string>& times_path = std::nullopt);

/// A 3x4 matrix as KITTI prints them (projection matrices, rigid transforms).
using Matrix34d = Eigen::Matrix<double, 3, 4>;

/// The content of a KITTI odometry `calib.txt`.
struct KittiCalib {
  /// Every `NAME: 12 numbers` line by name: "P0".."P3" (camera projections), "Tr".
  std::map<std::string, Matrix34d> matrices{};
  /// The velodyne-to-left-camera transform from "Tr" (or "Tr_velo_to_cam"), rotation
  /// projected onto SO(3), translation exact.
  Eigen::Isometry3d T_cam_velo = Eigen::Isometry3d::Identity();

  /// The matrix called `name`; throws core::Error when the file had none.
  [[nodiscard]] const Matrix34d& matrix(const std::string& name) const;
};

/// Reads a KITTI `calib.txt`. Throws core::FileError on a malformed line, a
/// repeated name, or when no "Tr" / "Tr_velo_to_cam" line is present.
KittiCalib readKittiCalib(const std::string& path);

}  // namespace dcl::io
