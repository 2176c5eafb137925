#include <array>
#include <charconv>
#include <cmath>
#include <ostream>
#include <span>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pose_file.hpp>

namespace dcl::io {
namespace {

using core::FileError;
using core::FileLocation;
using Tokens = std::vector<std::string_view>;

/// How far (Frobenius norm of R^T R - I) a printed rotation may be from SO(3).
constexpr double kRotationTolerance = 1e-2;
constexpr std::size_t kKittiFields = 12;
constexpr std::array<const char*, 8> kTumFields = {"t", "x", "y", "z", "qx", "qy", "qz", "qw"};

/// "r11".."r33" for the rotation entries, "tx", "ty", "tz" for the translation.
std::string kittiFieldName(std::size_t k) {
  const std::size_t row = k / 4;
  const std::size_t col = k % 4;
  std::string name(1, col == 3 ? 't' : 'r');
  // Appended piece by piece: GCC 12 warns (falsely) on `"r" + std::to_string(...)`.
  if (col == 3) return name.append(1, "xyz"[row]);
  return name.append(std::to_string(row + 1)).append(std::to_string(col + 1));
}

bool isBlank(std::string_view line) {
  return splitWhitespace(line).empty();
}

bool isCommentOrBlank(std::string_view line) {
  const auto tokens = splitWhitespace(line);
  return tokens.empty() || tokens.front().front() == '#';
}

double finiteNumber(const LineReader& in, std::string_view token, const std::string& field) {
  const double value = in.number<double>(token, field.c_str());
  if (!std::isfinite(value)) in.fail("'" + std::string(token) + "' is not finite", field);
  return value;
}

void requireCount(const LineReader& in, std::size_t found, std::size_t expected,
                  const char* layout) {
  if (found == expected) return;
  in.fail("expected " + std::to_string(expected) + " numbers (" + layout + "), found " +
          std::to_string(found));
}

/// Why `R` is not (close to) a rotation, or none.
std::optional<std::string> rotationProblem(const Eigen::Matrix3d& R) {
  const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
  if (!(error <= kRotationTolerance)) {  // NaN too: entries near 1e200 overflow R^T R
    return "rotation block is not orthonormal (|R^T R - I| = " + exactText(error) + ")";
  }
  if (R.determinant() < 0.0) return "rotation block is a reflection (determinant < 0)";
  return std::nullopt;
}

/// The pose of a printed 3x4 matrix, exactly as written (see the header on why).
Eigen::Isometry3d rigidFromMatrix(const Matrix34d& M) {
  return core::makePose(M.col(3), Eigen::Matrix3d(M.leftCols<3>()));
}

Matrix34d parseMatrix34(const LineReader& in, std::span<const std::string_view> tokens) {
  Matrix34d M;
  for (std::size_t k = 0; k < kKittiFields; ++k) {
    M(static_cast<Eigen::Index>(k / 4), static_cast<Eigen::Index>(k % 4)) =
        finiteNumber(in, tokens[k], kittiFieldName(k));
  }
  return M;
}

Eigen::Isometry3d parseKittiPose(const LineReader& in) {
  const Tokens tokens = splitWhitespace(in.line());
  requireCount(in, tokens.size(), kKittiFields, "row-major 3x4 matrix");
  const Matrix34d M = parseMatrix34(in, tokens);
  if (auto problem = rotationProblem(M.leftCols<3>())) in.fail(*problem);
  return rigidFromMatrix(M);
}

[[noreturn]] void failEmpty(const LineReader& in, const char* what) {
  throw FileError(FileLocation{in.path(), in.lineNumber() + 1},
                  std::string("no ") + what + " (empty or blank file)");
}

std::vector<Eigen::Isometry3d> readKittiMatrices(const std::string& path) {
  LineReader in(path);
  std::vector<Eigen::Isometry3d> poses;
  while (in.next()) {
    if (!isBlank(in.line())) poses.push_back(parseKittiPose(in));
  }
  if (poses.empty()) failEmpty(in, "poses");
  return poses;
}

std::vector<double> indexStamps(std::size_t n) {
  std::vector<double> stamps(n);
  for (std::size_t i = 0; i < n; ++i) stamps[i] = static_cast<double>(i);
  return stamps;
}

Eigen::Quaterniond parseQuaternion(const LineReader& in, const Tokens& tokens) {
  Eigen::Quaterniond q;
  q.x() = finiteNumber(in, tokens[4], "qx");
  q.y() = finiteNumber(in, tokens[5], "qy");
  q.z() = finiteNumber(in, tokens[6], "qz");
  q.w() = finiteNumber(in, tokens[7], "qw");
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionTolerance) {
    in.fail("quaternion norm " + exactText(norm) + " is not 1 (corrupt line?)");
  }
  return q;
}

void parseTumLine(const LineReader& in, core::Trajectory& out) {
  const Tokens tokens = splitWhitespace(in.line());
  requireCount(in, tokens.size(), kTumFields.size(), "t x y z qx qy qz qw");
  const double t = finiteNumber(in, tokens[0], "t");
  const Eigen::Vector3d p(finiteNumber(in, tokens[1], "x"), finiteNumber(in, tokens[2], "y"),
                          finiteNumber(in, tokens[3], "z"));
  out.push_back(t, core::makePose(p, parseQuaternion(in, tokens)));
}

void writeKittiLine(std::ostream& out, const Eigen::Isometry3d& T) {
  for (std::size_t k = 0; k < kKittiFields; ++k) {
    if (k > 0) out << ' ';
    out << exactText(
        T.matrix()(static_cast<Eigen::Index>(k / 4), static_cast<Eigen::Index>(k % 4)));
  }
  out << '\n';
}

void writeTumLine(std::ostream& out, double stamp, const Eigen::Isometry3d& T) {
  Eigen::Quaterniond q(T.linear());
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d& p = T.translation();
  out << exactText(stamp);
  for (const double v : {p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()}) {
    out << ' ' << exactText(v);
  }
  out << '\n';
}

void writeStamps(const std::string& path, const std::vector<double>& stamps) {
  writeFileAtomic(path, [&](std::ostream& out) {
    for (const double t : stamps) out << exactText(t) << '\n';
  });
}

void parseCalibLine(const LineReader& in, KittiCalib& calib) {
  const Tokens tokens = splitWhitespace(in.line());
  if (tokens.empty()) return;
  const std::string_view label = tokens.front();
  if (label.size() < 2 || label.back() != ':') in.fail("expected 'NAME: 12 numbers'", "name");
  const std::string name(label.substr(0, label.size() - 1));
  requireCount(in, tokens.size() - 1, kKittiFields, "row-major 3x4 matrix");
  const Matrix34d M = parseMatrix34(in, std::span(tokens).subspan(1));
  if (!calib.matrices.emplace(name, M).second) in.fail("repeated matrix", name);
}

/// The velodyne-to-camera transform of `calib`, from "Tr" or "Tr_velo_to_cam".
Eigen::Isometry3d velodyneToCamera(const std::string& path, const KittiCalib& calib) {
  for (const char* name : {"Tr", "Tr_velo_to_cam"}) {
    const auto it = calib.matrices.find(name);
    if (it == calib.matrices.end()) continue;
    if (auto problem = rotationProblem(it->second.leftCols<3>())) {
      throw FileError(FileLocation{path, std::nullopt, std::nullopt, name}, *problem);
    }
    // A calibration is a rigid transform used for geometry: its rotation is made exact.
    return core::makePose(it->second.col(3), core::projectToSO3(it->second.leftCols<3>()));
  }
  throw FileError({path}, "no 'Tr:' line (the velodyne-to-camera transform)");
}

}  // namespace

PoseFormat parsePoseFormat(std::string_view name) {
  if (name == "kitti") return PoseFormat::kitti;
  if (name == "tum") return PoseFormat::tum;
  throw core::Error("unknown pose format '" + std::string(name) + "' (expected kitti or tum)");
}

std::string_view toString(PoseFormat format) {
  return format == PoseFormat::kitti ? "kitti" : "tum";
}

std::vector<double> readKittiTimes(const std::string& path) {
  LineReader in(path);
  std::vector<double> stamps;
  std::size_t previous_line = 0;
  while (in.next()) {
    const Tokens tokens = splitWhitespace(in.line());
    if (tokens.empty()) continue;
    requireCount(in, tokens.size(), 1, "one time stamp a line");
    const double t = finiteNumber(in, tokens.front(), "t");
    if (!stamps.empty() && !(t > stamps.back())) {
      in.fail(std::string(t == stamps.back() ? "repeats" : "goes back before") + " the stamp " +
                  exactText(stamps.back()) + " of line " + std::to_string(previous_line) +
                  " (stamps must increase)",
              "t");
    }
    stamps.push_back(t);
    previous_line = in.lineNumber();
  }
  if (stamps.empty()) failEmpty(in, "time stamps");
  return stamps;
}

core::Trajectory readKittiPoses(const std::string& path,
                                const std::optional<std::string>& times_path) {
  std::vector<Eigen::Isometry3d> poses = readKittiMatrices(path);
  if (!times_path) return {indexStamps(poses.size()), std::move(poses)};
  std::vector<double> stamps = readKittiTimes(*times_path);
  if (stamps.size() != poses.size()) {
    throw FileError({*times_path}, "has " + std::to_string(stamps.size()) +
                                       " time stamps but the pose file " + path + " has " +
                                       std::to_string(poses.size()) + " poses");
  }
  return {std::move(stamps), std::move(poses)};
}

core::Trajectory readTumPoses(const std::string& path) {
  LineReader in(path);
  core::Trajectory trajectory;
  while (in.next()) {
    if (!isCommentOrBlank(in.line())) parseTumLine(in, trajectory);
  }
  if (trajectory.empty()) failEmpty(in, "poses");
  return trajectory;
}

void writeKittiPoses(const std::string& path, const core::Trajectory& trajectory,
                     const std::optional<std::string>& times_path) {
  writeFileAtomic(path, [&](std::ostream& out) {
    for (const auto& T : trajectory.poses()) writeKittiLine(out, T);
  });
  if (times_path) writeStamps(*times_path, trajectory.stamps());
}

void writeTumPoses(const std::string& path, const core::Trajectory& trajectory) {
  writeFileAtomic(path, [&](std::ostream& out) {
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
      writeTumLine(out, trajectory.stamp(i), trajectory.pose(i));
    }
  });
}

core::Trajectory readPoses(const std::string& path, PoseFormat format,
                           const std::optional<std::string>& times_path) {
  if (format == PoseFormat::kitti) return readKittiPoses(path, times_path);
  if (times_path) throw core::Error("a times file only goes with KITTI poses, not TUM: " + path);
  return readTumPoses(path);
}

void writePoses(const std::string& path, PoseFormat format, const core::Trajectory& trajectory,
                const std::optional<std::string>& times_path) {
  if (format == PoseFormat::kitti) return writeKittiPoses(path, trajectory, times_path);
  if (times_path) throw core::Error("a times file only goes with KITTI poses, not TUM: " + path);
  writeTumPoses(path, trajectory);
}

const Matrix34d& KittiCalib::matrix(const std::string& name) const {
  const auto it = matrices.find(name);
  if (it == matrices.end()) throw core::Error("calibration has no matrix '" + name + "'");
  return it->second;
}

KittiCalib readKittiCalib(const std::string& path) {
  LineReader in(path);
  KittiCalib calib;
  while (in.next()) parseCalibLine(in, calib);
  if (calib.matrices.empty()) failEmpty(in, "calibration matrices");
  calib.T_cam_velo = velodyneToCamera(path, calib);
  return calib;
}

}  // namespace dcl::io
