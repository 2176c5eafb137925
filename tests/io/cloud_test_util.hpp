#pragma once

// Helpers for the point-cloud reader tests: temporary files, byte edits and
// checks on the message of a core::FileError.

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/core/point_cloud.hpp>

namespace dcl::io::test {

/// This process's scratch folder (per process: ctest runs tests in parallel).
inline std::filesystem::path scratchRoot() {
  return std::filesystem::path(::testing::TempDir()) /
         ("dcl_io_clouds_" + std::to_string(::getpid()));
}

/// Removes the scratch folder when the test program ends.
class ScratchCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(scratchRoot(), ec);
  }
};
inline ::testing::Environment* const kScratchCleanup =
    ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

/// A fresh folder for one test, removed and recreated.
inline std::filesystem::path freshDir(const std::string& name) {
  const auto dir = scratchRoot() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// Writes `bytes` to `path` as they are.
inline void writeBytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// The whole content of `path`.
inline std::string readBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Success when `text` contains `part`.
inline ::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' lacks '" << part << "'";
}

/// The message of the core::FileError that `f` throws; a test failure (and "") if
/// it throws nothing or something else.
template <class F>
std::string fileError(F&& f) {
  try {
    f();
  } catch (const core::FileError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected core::FileError, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected core::FileError, nothing thrown";
  return {};
}

/// A cloud with every channel: point i at (i/4, -i/8, 3 + i/16), intensity 2i,
/// time i/1024, ring i % 64, plus a NaN point and extreme floats.
inline core::PointCloud fullCloud(std::size_t n) {
  core::PointCloud cloud;
  for (std::size_t i = 0; i < n; ++i) {
    const auto f = static_cast<float>(i);
    cloud.points.emplace_back(f / 4, -f / 8, 3 + f / 16);
    cloud.intensity.push_back(2 * f);
    cloud.time.push_back(f / 1024);
    cloud.ring.push_back(static_cast<std::uint16_t>(i % 64));
  }
  if (n > 2) cloud.points[1].x() = std::numeric_limits<float>::quiet_NaN();
  if (n > 3) cloud.points[2] = {1e-30f, -3.4e38f, 0.1f};
  return cloud;
}

/// Success when both clouds hold the same channels with the same bits (NaN equals NaN).
inline ::testing::AssertionResult sameCloud(const core::PointCloud& a, const core::PointCloud& b) {
  if (a.size() != b.size()) {
    return ::testing::AssertionFailure() << "sizes " << a.size() << " and " << b.size();
  }
  const auto same = [](float x, float y) { return x == y || (std::isnan(x) && std::isnan(y)); };
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (!same(a.points[i][k], b.points[i][k])) {
        return ::testing::AssertionFailure() << "point " << i << " coordinate " << k << ": "
                                             << a.points[i][k] << " vs " << b.points[i][k];
      }
    }
  }
  if (a.intensity != b.intensity) return ::testing::AssertionFailure() << "intensity differs";
  if (a.time != b.time) return ::testing::AssertionFailure() << "time differs";
  if (a.ring != b.ring) return ::testing::AssertionFailure() << "ring differs";
  return ::testing::AssertionSuccess();
}

/// The folder of the shared third-party data.
inline std::string dataDir() {
  return DCL_DATA_DIR;
}

}  // namespace dcl::io::test
