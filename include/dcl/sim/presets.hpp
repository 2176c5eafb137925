#pragma once

/// Named dataset recipes for `dcl-slam simulate --preset NAME`: which world,
/// which sensor, how high it is mounted and the robots' routes.

#include <cstdint>
#include <string>
#include <vector>

#include <dcl/sim/routes.hpp>

namespace dcl::sim {

/// A dataset recipe: everything the simulator needs besides the world generator.
struct Preset {
  std::string name{};             ///< the preset's name, e.g. "kitti05-3"
  std::string description{};      ///< one line for `--help` and dataset.yaml
  std::string world{};            ///< "city" | "campus" | "aliasing"
  std::string sensor{};           ///< "hdl64" | "vlp16"
  double mount_height = 1.73;     ///< m, sensor above the ground (KITTI's HDL-64: 1.73)
  std::vector<Route> routes{};    ///< one per robot, named "a", "b", ...
  std::uint64_t seed = 1;         ///< seeds the world, the routes and the sensor noise
  bool calibration_error = true;  ///< the robots' lasers off the published table (BeamCalibration)
  /// Every robot carries one LiDAR unit: a single car's drive split into
  /// robots, as the paper splits the KITTI sequences.
  bool shared_unit = false;
  /// Every robot carries an IMU that reads the direction up with each scan
  /// (io::SimSpec::imu), as KITTI's car carried its GPS/IMU and the paper's
  /// robots their LiDAR-inertial front-ends' IMUs.
  bool imu = false;
};

/// What the user may change about a preset.
struct PresetOptions {
  std::string data_dir{};  ///< the shared data folder (KITTI ground truth); KITTI presets need it
  std::uint64_t seed = 1;  ///< everything random derives from it
  int robots = 0;          ///< 0 = the preset's default; KITTI presets accept only their own count
  std::string sensor{};    ///< "" = the preset's default, else "hdl64" or "vlp16"
  /// The vehicles of generated routes rock on their suspension (rockBody);
  /// KITTI's routes, a real car's, rock already. Off by default: with it, the
  /// own-repeat test misses repeats the body's tilt disguises (BENCHMARKS,
  /// "The vehicle's body").
  bool body_motion = false;
};

/// The preset names, in the order `--help` lists them: kitti00-3, kitti05-3,
/// kitti08-2, campus-3, campus-9, aliasing-3, small-3, demo, crossing-2.
std::vector<std::string> presetNames();

/// Builds the preset `name`. Throws core::Error listing the names for an
/// unknown one, and for a bad sensor, a robot count a preset cannot give, or
/// KITTI ground truth missing under options.data_dir.
Preset makePreset(const std::string& name, const PresetOptions& options = {});

}  // namespace dcl::sim
