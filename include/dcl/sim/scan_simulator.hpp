#pragma once

/// Simulated LiDAR sweeps: Embree ray casting into a World along a moving
/// sensor's ground-truth trajectory, and into the world's moving actors
/// (Traffic) where they are at each column's time.

#include <cstdint>
#include <memory>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/sim/lidar_model.hpp>
#include <dcl/sim/traffic.hpp>
#include <dcl/sim/world.hpp>

namespace dcl::sim {

/// Switches of the sweep simulation.
struct ScanOptions {
  bool motion_distortion = true;  ///< fire each column from the pose at its own time
  bool noise = true;              ///< range noise and random dropout
  bool parallel = true;           ///< cast with TBB over all cores
};

/// Casts LiDAR sweeps into one world. Build once per world (it builds the
/// Embree scene), then call `scan` from any thread.
class ScanSimulator {
 public:
  /// The sweeps of `world` with its moving actors `traffic` (none by default;
  /// the scans of a world without traffic do not depend on this class's
  /// handling of actors).
  ScanSimulator(const World& world, LidarModel model, ScanOptions options = {},
                Traffic traffic = {});
  ~ScanSimulator();
  ScanSimulator(ScanSimulator&&) noexcept;
  ScanSimulator& operator=(ScanSimulator&&) noexcept;

  /// One revolution starting at `stamp` while the sensor moves along
  /// `T_world_sensor`. Points are in the sensor frame at the moment each was
  /// fired (as a driver delivers them: with motion distortion when the sensor
  /// moves), `time` is seconds since `stamp`, `ring` the beam index, `intensity`
  /// in [0, 1]. The scan's ground-truth pose is T_world_sensor at `stamp`.
  /// `unit` is the sensor's deviation from the model's beam table (empty: a
  /// perfect unit); it applies with or without ScanOptions::noise.
  /// Bit-identical for the same world, model, options, trajectory, stamp, seed
  /// and unit, whatever the number of threads.
  [[nodiscard]] core::PointCloud scan(const core::Trajectory& T_world_sensor, double stamp,
                                      std::uint64_t seed, const BeamCalibration& unit = {}) const;

  [[nodiscard]] const LidarModel& model() const;
  /// The world's moving actors.
  [[nodiscard]] const Traffic& traffic() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::sim
