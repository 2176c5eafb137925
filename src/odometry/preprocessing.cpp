#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <optional>
#include <utility>

#include <dcl/odometry/preprocessing.hpp>
#include <dcl/odometry/voxel_map.hpp>

namespace dcl::odometry {
namespace {

bool finite(const Eigen::Vector3f& p) {
  return std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(p.z());
}

/// Copies point `i` of `in` with the channels `out` carries.
void copyPoint(const core::PointCloud& in, std::size_t i, core::PointCloud& out) {
  out.points.push_back(in.points[i]);
  if (in.intensity.size() == in.size()) out.intensity.push_back(in.intensity[i]);
  if (in.time.size() == in.size()) out.time.push_back(in.time[i]);
  if (in.ring.size() == in.size()) out.ring.push_back(in.ring[i]);
}

/// Poses exp(t * velocity) at `bins` evenly spaced times over [t_min, t_max]: a
/// sweep's points need only a fine table, not one exp each (bins of 0.1 ms move
/// a car at 20 m/s by 2 mm).
std::vector<Eigen::Isometry3d> sweepPoses(const core::Vector6d& velocity, double t_min,
                                          double t_max, std::size_t bins) {
  std::vector<Eigen::Isometry3d> poses(bins);
  for (std::size_t i = 0; i < bins; ++i) {
    const double alpha = bins > 1 ? static_cast<double>(i) / static_cast<double>(bins - 1) : 0.0;
    poses[i] = core::expSE3((t_min + alpha * (t_max - t_min)) * velocity);
  }
  return poses;
}

/// The first and last point times of a sweep; none when points carry no times.
std::optional<std::pair<double, double>> sweepSpan(const core::PointCloud& cloud) {
  if (cloud.time.size() != cloud.size() || cloud.empty()) return std::nullopt;
  const auto [t_min, t_max] = std::minmax_element(cloud.time.begin(), cloud.time.end());
  return std::pair{static_cast<double>(*t_min), static_cast<double>(*t_max)};
}

}  // namespace

SweepMotion::SweepMotion(const core::Vector6d& velocity, double t_min, double t_max,
                         std::size_t bins)
    : poses_(sweepPoses(velocity, t_min, t_max, std::max<std::size_t>(bins, 1))),
      t_min_(t_min),
      scale_(t_max > t_min ? static_cast<double>(poses_.size() - 1) / (t_max - t_min) : 0.0) {}

const Eigen::Isometry3d& SweepMotion::at(double t) const {
  const double bin =
      std::clamp(std::round((t - t_min_) * scale_), 0.0, static_cast<double>(poses_.size() - 1));
  return poses_[static_cast<std::size_t>(bin)];
}

CleanScan cleanScan(const core::PointCloud& scan, double min_range, double max_range) {
  CleanScan result;
  const bool has_time = scan.time.size() == scan.size() && !scan.empty();
  result.cloud.reserve(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const Eigen::Vector3f& p = scan.points[i];
    if (!finite(p)) {
      ++result.non_finite;
    } else if (has_time && !std::isfinite(scan.time[i])) {
      ++result.bad_time;
    } else if (const double r = p.cast<double>().norm(); r < min_range || r > max_range) {
      ++result.out_of_range;
    } else {
      copyPoint(scan, i, result.cloud);
    }
  }
  return result;
}

std::vector<Eigen::Vector3d> toPoints(const core::PointCloud& cloud) {
  std::vector<Eigen::Vector3d> points(cloud.size());
  std::transform(cloud.points.begin(), cloud.points.end(), points.begin(),
                 [](const Eigen::Vector3f& p) { return p.cast<double>(); });
  return points;
}

core::PointCloud toCloud(std::span<const Eigen::Vector3d> points) {
  core::PointCloud cloud;
  cloud.points.resize(points.size());
  std::transform(points.begin(), points.end(), cloud.points.begin(),
                 [](const Eigen::Vector3d& p) { return p.cast<float>(); });
  return cloud;
}

std::vector<Eigen::Vector3d> deskew(const core::PointCloud& cloud, const core::Vector6d& velocity,
                                    double reference_time) {
  std::vector<Eigen::Vector3d> points = toPoints(cloud);
  const auto span = sweepSpan(cloud);
  if (!span) return points;
  const SweepMotion motion(velocity, span->first - reference_time, span->second - reference_time);
  for (std::size_t i = 0; i < points.size(); ++i)
    points[i] = motion.at(cloud.time[i] - reference_time) * points[i];
  return points;
}

double sweepMidTime(const core::PointCloud& cloud) {
  const auto span = sweepSpan(cloud);
  return span ? 0.5 * (span->first + span->second) : 0.0;
}

double sweepDuration(const core::PointCloud& cloud) {
  const auto span = sweepSpan(cloud);
  return span ? span->second - span->first : 0.0;
}

std::vector<std::size_t> voxelDownsampleIndices(std::span<const Eigen::Vector3d> points,
                                                double voxel_size) {
  // The voxels met so far, an open-addressing set at most half full (linear
  // probing): two allocations for the whole scan, where a node-based set
  // allocates one per voxel.
  const std::size_t slots = std::max<std::size_t>(64, std::bit_ceil(2 * points.size()));
  const int shift = 64 - std::countr_zero(slots);
  std::vector<Voxel> voxels(slots);
  std::vector<std::uint8_t> occupied(slots, 0);
  std::vector<std::size_t> kept;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Voxel voxel = voxelOf(points[i], voxel_size);
    std::size_t slot = voxelSlot(voxel, shift);
    while (occupied[slot] && voxels[slot] != voxel) slot = (slot + 1) & (slots - 1);
    if (occupied[slot]) continue;
    occupied[slot] = 1;
    voxels[slot] = voxel;
    kept.push_back(i);
  }
  return kept;
}

std::vector<Eigen::Vector3d> voxelDownsample(std::span<const Eigen::Vector3d> points,
                                             double voxel_size) {
  std::vector<Eigen::Vector3d> kept;
  for (const std::size_t i : voxelDownsampleIndices(points, voxel_size)) kept.push_back(points[i]);
  return kept;
}

}  // namespace dcl::odometry
