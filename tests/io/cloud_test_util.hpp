#pragma once

// Helpers for the point-cloud reader tests: clouds with every channel, and
// bit-exact comparison.

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/point_cloud.hpp>

#include "io_test_util.hpp"

namespace dcl::io::test {

/// `value`'s bytes appended to `out`, as a binary file stores them.
template <class T>
void append(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out.append(bytes, sizeof(T));
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
