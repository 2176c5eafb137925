#pragma once

/// Test helpers of the eval suite: small pose-file readers (independent of dcl::io), the shared
/// data folder, synthetic trajectories, and a runner for tests/eval/reference_metrics.py.

#include <Eigen/Geometry>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <dcl/core/se3.hpp>
#include <dcl/core/trajectory.hpp>

namespace dcl::eval::test {

/// A file of the shared data folder's evo trajectories.
inline std::string evoData(const std::string& name) {
  return std::string(DCL_DATA_DIR) + "/trajectories/evo/" + name;
}

/// A KITTI pose file (12 numbers a line, row-major [R|t]); stamps are the line indices.
inline core::Trajectory readKitti(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot be opened");
  core::Trajectory trajectory;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    Eigen::Matrix<double, 3, 4, Eigen::RowMajor> m;
    for (int k = 0; k < 12; ++k) fields >> m.data()[k];
    if (!fields) continue;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.matrix().topRows<3>() = m;
    trajectory.push_back(static_cast<double>(trajectory.size()), T);
  }
  return trajectory;
}

/// A TUM pose file ("stamp x y z qx qy qz qw" a line, '#' comments).
inline core::Trajectory readTum(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot be opened");
  core::Trajectory trajectory;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double t, x, y, z, qx, qy, qz, qw;
    if (!(fields >> t >> x >> y >> z >> qx >> qy >> qz >> qw)) continue;
    trajectory.push_back(
        t, core::makePose(Eigen::Vector3d(x, y, z), Eigen::Quaterniond(qw, qx, qy, qz)));
  }
  return trajectory;
}

/// A wavy 3D path of `n` poses, 0.1 s apart, turning as it goes (not collinear).
inline core::Trajectory wavyPath(std::size_t n, double t0 = 0.0) {
  core::Trajectory trajectory;
  for (std::size_t i = 0; i < n; ++i) {
    const double s = 0.1 * static_cast<double>(i);
    const Eigen::Vector3d p(10.0 * std::cos(0.3 * s), 8.0 * std::sin(0.5 * s), 0.5 * s);
    const Eigen::Vector3d omega(0.05 * std::sin(s), 0.02 * s, 0.3 * s);
    trajectory.push_back(t0 + s, core::makePose(p, core::expSO3(omega)));
  }
  return trajectory;
}

/// Runs tests/eval/reference_metrics.py with `arguments` and parses its JSON; none when Debian's
/// Python with numpy is not there (the caller skips).
inline std::optional<nlohmann::json> runReference(const std::string& arguments) {
  const std::string python = "/usr/bin/python3";
  if (std::system((python + " -c 'import numpy' > /dev/null 2>&1").c_str()) != 0)
    return std::nullopt;
  const auto out = std::filesystem::temp_directory_path() /
                   ("dcl_eval_reference_" + std::to_string(::getpid()) + ".json");
  const std::string script = std::string(DCL_SOURCE_DIR) + "/tests/eval/reference_metrics.py";
  const std::string command =
      python + " '" + script + "' " + arguments + " > '" + out.string() + "'";
  if (std::system(command.c_str()) != 0) return nlohmann::json();
  std::ifstream in(out);
  nlohmann::json result = nlohmann::json::parse(in);
  std::filesystem::remove(out);
  return result;
}

/// Arguments naming the KITTI_00 ground truth and an estimate of the shared data folder.
inline std::string kittiArguments(const std::string& estimate) {
  return "--gt '" + evoData("KITTI_00_gt.txt") + "' --est '" + evoData(estimate) +
         "' --format kitti";
}

/// True when |a - b| <= rel * max(|a|, |b|) + abs.
inline bool near(double a, double b, double rel, double abs = 1e-12) {
  return std::abs(a - b) <= rel * std::max(std::abs(a), std::abs(b)) + abs;
}

}  // namespace dcl::eval::test
