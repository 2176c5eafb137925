#pragma once

/// Simulated datasets: a folder holding only dataset.yaml and the robots'
/// ground truth, whose scans are regenerated on demand, bit-identically, from
/// the world kind, the seed, the sensor and the ground truth.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/scan_source.hpp>
#include <dcl/sim/imu_model.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/scan_simulator.hpp>
#include <dcl/sim/traffic.hpp>
#include <dcl/sim/world.hpp>
#include <dcl/sim/world_gen.hpp>

namespace dcl::sim {

/// How a simulated dataset's scans are computed (never changes their content).
struct SimWorldOptions {
  bool parallel = true;  ///< cast each scan with TBB over all cores; off to parallelise over scans
  /// Keep the scans in the folder the environment's DCL_SCAN_CACHE names,
  /// when it names one, and read them back instead of casting them again
  /// (at most DCL_SCAN_CACHE_MB megabytes, 2048 by default; the files used
  /// longest ago go first). Off: every scan is cast. Default on.
  bool scan_cache = true;
};

/// The environment variables of SimWorldOptions::scan_cache.
inline constexpr const char* kScanCacheVariable = "DCL_SCAN_CACHE";
inline constexpr const char* kScanCacheSizeVariable = "DCL_SCAN_CACHE_MB";

/// What a simulated dataset regenerates its scans from: every robot's ground
/// truth (T_world_sensor), the world generated around them, and the scan
/// simulator of that world. Built once, shared by the robots' sources; `scan`
/// may be called from any thread.
class SimWorld {
 public:
  /// Reads every robot's ground truth and builds the world (this takes a while
  /// for long routes). Throws core::Error when the dataset has no `sim` section,
  /// names an unknown sensor, or a robot lacks ground truth, or when
  /// DCL_SCAN_CACHE_MB is not a whole number, and core::FileError when a
  /// ground-truth file cannot be read.
  explicit SimWorld(const io::DatasetSpec& spec, const SimWorldOptions& options = {});
  ~SimWorld();
  SimWorld(const SimWorld&) = delete;
  SimWorld& operator=(const SimWorld&) = delete;

  /// Scan `index` of robot `robot`: the sweep starting at its ground-truth
  /// stamp, by the robot's own unit (perfect without noise or calibration error).
  /// Throws core::Error for an index past the robot's ground truth.
  [[nodiscard]] core::PointCloud scan(std::size_t robot, std::size_t index) const;

  /// Robot `robot`'s IMU reading of up at scan `index` (sim::readUp: its
  /// unit's tilt, the first robot's when shared, and the reading's noise);
  /// none when the dataset's robots carry no IMU. Throws like `scan`.
  [[nodiscard]] std::optional<Eigen::Vector3d> up(std::size_t robot, std::size_t index) const;

  /// Number of robots.
  [[nodiscard]] std::size_t robots() const;
  /// The LiDAR unit robot `robot` carries: its lasers' errors against the
  /// published table (empty: perfect lasers). The same unit for every robot
  /// when the dataset says `shared_unit`.
  [[nodiscard]] const BeamCalibration& unit(std::size_t robot) const;
  /// Ground truth T_world_sensor of robot `robot`; one scan per pose.
  [[nodiscard]] const core::Trajectory& groundTruth(std::size_t robot) const;
  /// The dataset it was built from.
  [[nodiscard]] const io::DatasetSpec& dataset() const;
  /// The generated world.
  [[nodiscard]] const World& world() const;
  /// The scan simulator of the world.
  [[nodiscard]] const ScanSimulator& simulator() const;
  /// Scans read from the scan cache so far, and scans cast and stored in it
  /// (both 0 without one).
  [[nodiscard]] std::uint64_t cachedScansRead() const;
  [[nodiscard]] std::uint64_t cachedScansStored() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The world generator of `kind` applied to `request`.
World generateWorldOfKind(io::WorldKind kind, const WorldRequest& request);

/// The moving actors of a world of `kind` around `request`'s routes, at
/// `density` times the kind's own traffic (0: none).
Traffic generateTrafficOfKind(io::WorldKind kind, const WorldRequest& request, double density);

/// The noise seed of scan `index` of robot `robot` in a dataset seeded `dataset_seed`
/// (a hash: neighbouring scans and robots get unrelated seeds).
std::uint64_t scanSeed(std::uint64_t dataset_seed, std::size_t robot, std::size_t index);

/// The seed robot `robot`'s LiDAR unit (BeamCalibration) is drawn from: every
/// robot carries its own unit, with its own lasers' biases.
std::uint64_t unitSeed(std::uint64_t dataset_seed, std::size_t robot);

/// One robot's regenerated scans, as a ScanSource (stamps from its ground truth).
class SimScanSource final : public io::ScanSource {
 public:
  /// The scans of robot `robot` of `world`.
  SimScanSource(std::shared_ptr<const SimWorld> world, std::size_t robot);

  /// Number of ground-truth poses.
  [[nodiscard]] std::size_t size() const override;
  /// Stamp of ground-truth pose `i`.
  [[nodiscard]] double stamp(std::size_t i) const override;
  /// SimWorld::scan of this robot (x y z intensity time ring).
  [[nodiscard]] core::PointCloud scan(std::size_t i) const override;
  /// SimWorld::up of this robot.
  [[nodiscard]] std::optional<Eigen::Vector3d> up(std::size_t i) const override;
  /// "simulated robot 'NAME' of dataset 'NAME'".
  [[nodiscard]] std::string describe() const override;

 private:
  std::shared_ptr<const SimWorld> world_;
  std::size_t robot_;
};

/// s between a recorded scan's stamp and the IMU reading that levels it, at most.
inline constexpr double kImuMaxGap = 0.05;

/// The scans of robot `robot` of any dataset: regenerated for a simulated robot
/// (from `world`, built on first need when null and the robot needs it), read
/// from disk otherwise (ros2::McapScanSource for an MCAP file, io::BagScanSource
/// for a ROS 1 bag, io::openScanSource for the rest); a bag's scans with an
/// `imu_topic` are levelled by its readings (msg::LevelledScanSource).
std::unique_ptr<io::ScanSource> openRobotScans(const io::DatasetSpec& spec, std::size_t robot,
                                               std::shared_ptr<const SimWorld> world = nullptr);

/// The scans of every robot of a dataset; simulated robots share one SimWorld.
std::vector<std::unique_ptr<io::ScanSource>> openDatasetScans(const io::DatasetSpec& spec,
                                                              const SimWorldOptions& options = {});

/// What writeSimDataset may switch off in the sensor simulation.
struct SimDatasetOptions {
  bool motion_distortion = true;  ///< scans distorted by the motion during the sweep; default on
  bool noise = true;              ///< range noise and dropout; default on
  bool calibration_error =
      true;  ///< with noise: each robot's own lasers' errors where the preset has them; default on
  double traffic = 0.0;  ///< moving actors, times the world kind's own traffic; default none
  bool imu = true;  ///< each robot's IMU reading of up with its scans, where the preset has one
};

/// Writes a simulated dataset for `preset` into `folder`: dataset.yaml and one
/// TUM ground-truth file per robot (`ground_truth/NAME.tum`), no scans. Returns
/// the dataset as read back from the folder (what every reader will see).
io::DatasetSpec writeSimDataset(const std::string& folder, const Preset& preset,
                                const SimDatasetOptions& options = {});

}  // namespace dcl::sim
