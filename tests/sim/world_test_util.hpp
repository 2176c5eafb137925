#pragma once

// Helpers shared by the world, preview and realism tests: small analytic
// routes, a KITTI excerpt, and brute-force geometric queries on a World.

#include <algorithm>
#include <cmath>
#include <optional>
#include <span>
#include <string>

#include <dcl/core/se3.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/sim/routes.hpp>
#include <dcl/sim/world.hpp>

namespace dcl::sim::test {

inline constexpr double kMount = 1.73;  ///< m, sensor above the road in these tests

/// A pose at (x, y, z) heading along (dx, dy), level.
inline Eigen::Isometry3d headingPose(double x, double y, double z, double dx, double dy) {
  Eigen::Isometry3d T = core::makePose2d(x, y, std::atan2(dy, dx));
  T.translation().z() = z;
  return T;
}

/// A winding, climbing route along +x: y = 15 sin(x / 40), 4 % grade plus a
/// 0.5 m swell, a pose every metre (10 Hz at 10 m/s).
inline core::Trajectory windingRoute(double length, double y0 = 0.0) {
  core::Trajectory route;
  for (int i = 0; i <= static_cast<int>(length); ++i) {
    const double x = i, y = y0 + 15.0 * std::sin(x / 40.0);
    const double z = kMount + 0.04 * x + 0.5 * std::sin(x / 30.0);
    route.push_back(0.1 * i, headingPose(x, y, z, 1.0, 15.0 / 40.0 * std::cos(x / 40.0)));
  }
  return route;
}

/// A straight level route from (x0, y) along `direction` (+1: +x, -1: -x), a pose every metre.
inline core::Trajectory straightRoute(double x0, double y, double length, double direction = 1.0) {
  core::Trajectory route;
  for (int i = 0; i <= static_cast<int>(length); ++i)
    route.push_back(0.1 * i, headingPose(x0 + direction * i, y, kMount, direction, 0.0));
  return route;
}

/// The first `metres` of KITTI 05's ground truth in the LiDAR frame.
inline core::Trajectory kittiExcerpt(double metres, const std::string& sequence = "05") {
  const auto files = kittiFiles(DCL_DATA_DIR, sequence);
  const core::Trajectory full = loadKittiLidarTrajectory(files.poses, files.calib, files.times);
  const auto distances = full.distances();
  core::Trajectory out;
  for (std::size_t i = 0; i < full.size() && distances[i] <= metres; ++i)
    out.push_back(full.stamp(i), full.pose(i));
  return out;
}

/// Horizontal distance from `p` to the triangle's projection (0 inside).
inline double distanceToTriangle2d(const Eigen::Vector2d& p,
                                   const std::array<Eigen::Vector2d, 3>& t) {
  const auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() * b.y() - a.y() * b.x();
  };
  const double c0 = cross(t[1] - t[0], p - t[0]), c1 = cross(t[2] - t[1], p - t[1]);
  const double c2 = cross(t[0] - t[2], p - t[2]);
  if ((c0 >= 0 && c1 >= 0 && c2 >= 0) || (c0 <= 0 && c1 <= 0 && c2 <= 0)) return 0.0;
  double best = 1e300;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector2d a = t[i], ab = t[(i + 1) % 3] - a;
    const double f =
        ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    best = std::min(best, (a + f * ab - p).norm());
  }
  return best;
}

inline std::array<Eigen::Vector2d, 3> triangle2d(const World& world, std::size_t t) {
  std::array<Eigen::Vector2d, 3> out;
  for (int k = 0; k < 3; ++k)
    out[k] = world.vertices[world.triangles[t][k]].head<2>().cast<double>();
  return out;
}

/// Triangles other than road, kerb and ground within `radius` (horizontally) of a route pose.
inline std::size_t obstaclesNearRoutes(const World& world, std::span<const core::Trajectory> routes,
                                       double radius) {
  std::size_t count = 0;
  for (std::size_t t = 0; t < world.triangleCount(); ++t) {
    const Surface s = world.surfaces[t];
    if (s == Surface::road || s == Surface::kerb || s == Surface::ground) continue;
    const auto tri = triangle2d(world, t);
    Eigen::AlignedBox2d box;
    for (const auto& v : tri) box.extend(v);
    box.min().array() -= radius;
    box.max().array() += radius;
    bool near = false;
    for (const auto& route : routes)
      for (const auto& T : route.poses()) {
        const Eigen::Vector2d p = T.translation().head<2>();
        if (!near && box.contains(p) && distanceToTriangle2d(p, tri) < radius) near = true;
      }
    count += near;
  }
  return count;
}

/// What a ray cast straight down from `p` hits first: its height and surface.
struct DownHit {
  double z = 0.0;
  Surface surface = Surface::ground;
};

inline std::optional<DownHit> castDown(const World& world, const Eigen::Vector3d& p) {
  std::optional<DownHit> best;
  for (std::size_t t = 0; t < world.triangleCount(); ++t) {
    const auto tri = triangle2d(world, t);
    if (distanceToTriangle2d(p.head<2>(), tri) > 0.0) continue;
    std::array<Eigen::Vector3d, 3> v;
    for (int k = 0; k < 3; ++k) v[k] = world.vertices[world.triangles[t][k]].cast<double>();
    const Eigen::Vector3d n = (v[1] - v[0]).cross(v[2] - v[0]);
    if (std::abs(n.z()) < 1e-9) continue;  // vertical: a ray down grazes it
    const double z = v[0].z() - (n.x() * (p.x() - v[0].x()) + n.y() * (p.y() - v[0].y())) / n.z();
    if (z > p.z() || (best && z <= best->z)) continue;
    best = DownHit{z, world.surfaces[t]};
  }
  return best;
}

}  // namespace dcl::sim::test
