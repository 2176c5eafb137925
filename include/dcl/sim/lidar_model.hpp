#pragma once

/// Spinning LiDAR beam models: which elevations, how many columns a sweep,
/// range limits and the sensor's imperfections.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace dcl::sim {

/// A spinning multi-beam LiDAR.
struct LidarModel {
  std::string name;                    ///< "hdl64", "vlp16"
  std::vector<double> elevations_deg;  ///< beam elevation by ring index (ring 0 first)
  int columns = 2000;                  ///< firings per revolution
  double rate_hz = 10.0;               ///< revolutions per second
  double min_range = 0.9;              ///< m, closer returns are dropped
  double max_range = 120.0;            ///< m, no return past this
  double range_noise_sigma = 0.02;     ///< m, Gaussian range noise at zero range
  /// Growth of the range noise with range: its sigma at range r is
  /// min(range_noise_sigma + range_noise_per_m * r, range_noise_max).
  double range_noise_per_m = 0.0;
  double range_noise_max = 1.0;  ///< m
  double dropout = 0.03;         ///< share of beams that return nothing at random
  /// Weak echoes fade: a return of noiseless intensity 0 is lost with this
  /// probability on top of `dropout`, falling linearly to none at `dark_intensity`.
  double dark_dropout = 0.0;
  double dark_intensity = 0.1;
  /// Chance that a beam whose footprint straddles a depth edge (the next beam
  /// of its ring returns more than a metre and 20 % nearer or farther) reports
  /// a range between the two surfaces, as the echoes of both merge.
  double mixed_pixel_rate = 0.0;
  /// Mean depth (m, exponential) a beam goes into foliage before it returns:
  /// leaves scatter the returns of a crown or hedge through its outer layer.
  double foliage_depth = 0.0;
  /// deg, Gaussian jitter of each firing's azimuth (the lasers' timing); the
  /// point is reported along the azimuth it was really fired at.
  double azimuth_jitter_deg = 0.0;
  /// Every `half_step_period` firings on average (0: never), a firing comes
  /// half an azimuth step after the one before it, along every ring, as about
  /// one step in seven of KITTI's HDL-64E does. At least 2 when set.
  double half_step_period = 0.0;
  /// What a unit's factory calibration leaves: each laser's true elevation
  /// and range zero deviate from the published table by a fixed amount, drawn
  /// once per unit (BeamCalibration) with these standard deviations. The
  /// driver converts with the table, so every point of that laser carries the
  /// same bias, scan after scan: the main cause of a LiDAR odometry's drift,
  /// which white range noise averages away.
  double elevation_error_sigma_deg = 0.0;  ///< deg, per laser
  double range_offset_sigma = 0.0;         ///< m, per laser
  /// The part of the elevation error every laser of a unit shares (the whole
  /// head tilted against its table, the lasers' fan opened or closed), drawn
  /// once per unit around `elevation_bias_mean_deg`. KITTI's HDL-64E needs
  /// every elevation raised by about 0.2 deg (0.22 deg in IMLS-SLAM, 0.205 in
  /// the KITTI loaders of KISS-ICP and pyLiDAR-SLAM): a cone-shaped
  /// distortion of each scan, the same in every scan, that no registration
  /// can undo and that makes a LiDAR odometry drift several times more than
  /// per-laser errors do.
  double elevation_bias_mean_deg = 0.0;
  double elevation_bias_sigma_deg = 0.0;
  double mount_height = 1.73;  ///< m, sensor above the ground on its vehicle
  /// The carrying vehicle's body as a box in the sensor frame (x forward, z up):
  /// beams that meet it return nothing, as on KITTI, whose car hides the lowest
  /// beams ahead and behind. None: nothing of the vehicle is in view.
  std::optional<Eigen::AlignedBox3d> ego_body = std::nullopt;

  /// Seconds one revolution takes.
  [[nodiscard]] double sweepDuration() const { return 1.0 / rate_hz; }
  /// Where in the revolution column `column` fires, in [0, 1): evenly spaced
  /// columns, or with a half step every `half_step_period` firings.
  [[nodiscard]] double columnPhase(int column) const;
  /// Beams times columns.
  [[nodiscard]] std::size_t raysPerScan() const { return elevations_deg.size() * columns; }

  /// Velodyne HDL-64E as on KITTI: 64 beams from +2 to -24.8 deg, 2160 columns
  /// with KITTI's half steps, 120 m.
  static LidarModel hdl64();
  /// Velodyne VLP-16: 16 beams at +/-15 deg (2 deg apart), 1800 columns, 100 m.
  static LidarModel vlp16();
  /// "hdl64" or "vlp16"; throws core::Error naming the accepted names otherwise.
  static LidarModel byName(std::string_view name);
};

/// One unit's deviation from its model's beam table (LidarModel's
/// elevation_error_sigma_deg, range_offset_sigma and the elevation bias).
/// Empty: a perfect unit.
struct BeamCalibration {
  std::vector<double> elevation_error_deg;  ///< true minus tabled elevation, per ring
  double elevation_bias_deg = 0.0;          ///< true minus tabled elevation of every ring alike
  std::vector<double> range_offset;         ///< m, added to every range of the ring

  /// Draws a unit of `model` from `seed`: the same seed, the same unit.
  static BeamCalibration draw(const LidarModel& model, std::uint64_t seed);
  [[nodiscard]] bool empty() const { return elevation_error_deg.empty(); }
};

}  // namespace dcl::sim
