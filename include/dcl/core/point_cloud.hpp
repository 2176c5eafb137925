#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace dcl::core {

/// A LiDAR scan or map as structure-of-arrays: xyz in float (sensor precision),
/// and optional per-point channels. A channel is either empty (absent) or
/// exactly as long as `points`.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;  ///< metres, in the cloud's frame
  std::vector<float> intensity;         ///< reflectance as the sensor reports it (optional)
  std::vector<float> time;              ///< seconds relative to the scan's stamp (optional)
  std::vector<std::uint16_t> ring;      ///< laser (beam) index (optional)

  [[nodiscard]] std::size_t size() const { return points.size(); }
  [[nodiscard]] bool empty() const { return points.empty(); }
  [[nodiscard]] bool hasIntensity() const { return !intensity.empty(); }
  [[nodiscard]] bool hasTime() const { return !time.empty(); }
  [[nodiscard]] bool hasRing() const { return !ring.empty(); }

  /// True when every present channel has one value per point.
  [[nodiscard]] bool consistent() const;

  void reserve(std::size_t n);
  void clear();

  /// Appends the channels of `other` (both must carry the same channels, or this one be empty).
  void append(const PointCloud& other);

  /// Maps every point by `T_target_source`, in place.
  void transform(const Eigen::Isometry3d& T_target_source);
};

/// A copy of `cloud` mapped by `T_target_source`.
PointCloud transformed(const PointCloud& cloud, const Eigen::Isometry3d& T_target_source);

}  // namespace dcl::core
