#pragma once

// Helpers for the simulated-dataset tests: a tiny two-robot preset that
// generates in well under a second, scratch folders, bit-exact cloud equality.

#include <cmath>
#include <filesystem>
#include <string>
#include <system_error>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/sim/presets.hpp>

namespace dcl::sim::test {

/// This process's scratch folder (per process: ctest runs tests in parallel),
/// removed with everything in it when the test program ends.
inline const std::filesystem::path& scratchRoot() {
  struct Root {
    std::filesystem::path path =
        std::filesystem::path(::testing::TempDir()) / ("dcl_sim_" + std::to_string(::getpid()));
    ~Root() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Root root;
  return root.path;
}

/// A fresh scratch folder named after the running test.
inline std::filesystem::path freshDir(const std::string& suffix = "") {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const auto dir =
      scratchRoot() / (std::string(info->test_suite_name()) + "_" + info->name() + suffix);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// A route of `n` poses at 10 Hz from (x0, y0), heading `yaw`, 2 m/s, turning gently.
inline core::Trajectory straightRoute(double x0, double y0, double yaw, int n) {
  core::Trajectory route;
  for (int i = 0; i < n; ++i) {
    const double s = 0.2 * i;
    const double heading = yaw + 0.01 * i;
    route.push_back(0.1 * i,
                    core::makePose2d(x0 + s * std::cos(yaw), y0 + s * std::sin(yaw), heading));
  }
  return route;
}

/// Two VLP-16 robots passing each other in a city street: a drives +x, b drives -x.
inline Preset tinyPreset(std::uint64_t seed = 7, int poses = 6) {
  Preset preset;
  preset.name = "tiny";
  preset.description = "two robots, a few scans";
  preset.world = "city";
  preset.sensor = "vlp16";
  preset.mount_height = 1.73;
  preset.seed = seed;
  preset.routes = {Route{"a", straightRoute(0.0, -1.5, 0.0, poses)},
                   Route{"b", straightRoute(3.0, 1.5, M_PI, poses)}};
  return preset;
}

/// Success when both clouds hold the same channels with the same bits.
inline ::testing::AssertionResult sameCloud(const core::PointCloud& a, const core::PointCloud& b) {
  if (a.size() != b.size()) {
    return ::testing::AssertionFailure() << "sizes " << a.size() << " and " << b.size();
  }
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a.points[i] != b.points[i]) return ::testing::AssertionFailure() << "point " << i;
  }
  if (a.intensity != b.intensity) return ::testing::AssertionFailure() << "intensity differs";
  if (a.time != b.time) return ::testing::AssertionFailure() << "time differs";
  if (a.ring != b.ring) return ::testing::AssertionFailure() << "ring differs";
  return ::testing::AssertionSuccess();
}

}  // namespace dcl::sim::test
