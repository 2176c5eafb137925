#include <cmath>

#include <dcl/core/error.hpp>
#include <dcl/sim/lidar_model.hpp>

#include "world_detail.hpp"

namespace dcl::sim {
namespace {

/// What a factory calibration leaves of each laser's error, for both models:
/// a tenth of a degree or two of elevation and centimetres of range (KITTI's
/// HDL-64E scans need every elevation raised by about 0.22 deg to lie flat,
/// as IMLS-SLAM found; the VLP-16 data sheet gives +/-3 cm of range
/// accuracy). White range noise averages out within a scan; these errors do
/// not, and they are what makes real LiDAR odometry drift. With perfect
/// lasers the simulated campus-3 robot a drifted 0.05 % of its distance
/// (KITTI metric), with these 0.15 %.
constexpr double kElevationErrorSigmaDeg = 0.15;
constexpr double kRangeOffsetSigma = 0.02;
/// The unit-wide elevation error (LidarModel::elevation_bias_mean_deg) of
/// KITTI's HDL-64E, as the published corrections of its scans give it. The
/// VLP-16 has none: no real sweep of one is at hand to measure it on, and
/// two units of opposite errors of that size no longer verify each other's
/// places where the crossing preset's robots meet.
constexpr double kKittiElevationBiasDeg = 0.205;

/// The imperfections of a Velodyne's returns, each brought within the band of
/// the real KITTI 00 HDL-64E sweeps in the shared data (`dcl-slam bench
/// sensor`, BENCHMARKS.md "Sensor against real scans"): range noise growing
/// from 1.2 cm near to 3.5 cm at 23 m and beyond, one firing in 330 lost at
/// random and up to 15 % of the darkest echoes (below intensity 0.08), one
/// beam in twenty at a depth edge mixed, 0.003 deg of firing-time jitter, and
/// returns from foliage scattered 0.3 m deep on average into a crown, hedge or
/// shrub (their 90th-percentile spread 9.0-10.1 cm on KITTI 00). The VLP-16
/// shares them (no real VLP-16 sweep to measure).
void applyMeasuredImperfections(LidarModel& model) {
  model.range_noise_sigma = 0.012;
  model.range_noise_per_m = 0.001;
  model.range_noise_max = 0.035;
  model.dropout = 0.003;
  model.dark_dropout = 0.15;
  model.dark_intensity = 0.08;
  model.mixed_pixel_rate = 0.05;
  model.foliage_depth = 0.3;
  model.azimuth_jitter_deg = 0.003;
}

// Rings are ordered by elevation, lowest beam first (ring 0 at the bottom), as
// the ROS velodyne driver numbers them: a bag exported from the simulator reads
// like one recorded with that driver, whatever the laser firing order.

/// HDL-64E as mounted on KITTI: two blocks of 32 lasers. The upper block
/// spans +2.0 to -8.33 deg at 1/3 deg, the lower -8.83 to -24.8 deg at about
/// 0.515 deg (the data sheet's 26.8 deg field of view, evenly split). Real
/// units deviate by a few hundredths of a degree per laser from this table.
std::vector<double> hdl64Elevations() {
  constexpr int kBlock = 32;
  std::vector<double> top_down;
  top_down.reserve(2 * kBlock);
  for (int i = 0; i < kBlock; ++i) top_down.push_back(2.0 - i / 3.0);
  const double lower_step = (24.8 - 8.83) / (kBlock - 1);
  for (int i = 0; i < kBlock; ++i) top_down.push_back(-8.83 - i * lower_step);
  return {top_down.rbegin(), top_down.rend()};
}

/// VLP-16: 16 lasers from -15 to +15 deg, 2 deg apart. The unit fires them
/// interleaved (-15, +1, -13, +3, ...); rings here are sorted by elevation.
std::vector<double> vlp16Elevations() {
  std::vector<double> elevations;
  for (int i = 0; i < 16; ++i) elevations.push_back(-15.0 + 2.0 * i);
  return elevations;
}

/// KITTI's VW Passat below its Velodyne, up to the bonnet and boot lid: 4.7 m
/// long from 1.9 m behind the sensor, 1.82 m wide, its top 0.75 m below the
/// sensor. It hides the lowest beams in arcs ahead and behind: of the ring at
/// -20 deg about 14 % (KITTI 00 frame 0: 18 %), at -24 deg about 36 % (44 %).
/// The cabin is left out: the Velodyne's mount lifts it clear of the roof.
Eigen::AlignedBox3d kittiCarBody() {
  return {Eigen::Vector3d(-1.9, -0.91, -1.48), Eigen::Vector3d(2.8, 0.91, -0.75)};
}

}  // namespace

double LidarModel::columnPhase(int column) const {
  if (!(half_step_period > 0.0)) return static_cast<double>(column) / columns;
  // In full steps from column 0: each completed period gives back half a step.
  const auto position = [&](int c) { return c - 0.5 * std::floor(c / half_step_period); };
  return position(column) / position(columns);
}

LidarModel LidarModel::hdl64() {
  LidarModel model;
  model.name = "hdl64";
  model.elevations_deg = hdl64Elevations();
  // KITTI's rings step 0.179 deg from firing to firing, but every 6.8th
  // step or so is half that (15 % of the steps): up to 2160 firings a ring.
  model.columns = 2160;
  model.half_step_period = 6.8;
  model.rate_hz = 10.0;
  model.min_range = 0.9;
  // The data sheet's 120 m; KITTI's published scans stop at about 80 m
  // (dark targets fade out earlier), which the intensity model does not cut.
  model.max_range = 120.0;
  applyMeasuredImperfections(model);
  model.elevation_error_sigma_deg = kElevationErrorSigmaDeg;
  model.range_offset_sigma = kRangeOffsetSigma;
  model.elevation_bias_mean_deg = kKittiElevationBiasDeg;
  model.mount_height = 1.73;  // KITTI's Velodyne above the road
  model.ego_body = kittiCarBody();
  return model;
}

LidarModel LidarModel::vlp16() {
  LidarModel model;
  model.name = "vlp16";
  model.elevations_deg = vlp16Elevations();
  model.columns = 1800;  // 0.2 deg at 10 Hz, as the data sheet gives
  model.rate_hz = 10.0;
  model.min_range = 0.5;
  model.max_range = 100.0;
  applyMeasuredImperfections(model);
  model.elevation_error_sigma_deg = kElevationErrorSigmaDeg;
  model.range_offset_sigma = kRangeOffsetSigma;
  model.mount_height = 0.7;       // on top of a Husky/Jackal-size ground robot
  model.ego_body = std::nullopt;  // a small robot's body stays below the -15 deg cone
  return model;
}

BeamCalibration BeamCalibration::draw(const LidarModel& model, std::uint64_t seed) {
  BeamCalibration unit;
  if (model.elevation_error_sigma_deg <= 0.0 && model.range_offset_sigma <= 0.0 &&
      model.elevation_bias_mean_deg == 0.0 && model.elevation_bias_sigma_deg <= 0.0) {
    return unit;
  }
  detail::Rng random(seed);
  for (std::size_t ring = 0; ring < model.elevations_deg.size(); ++ring) {
    unit.elevation_error_deg.push_back(model.elevation_error_sigma_deg * random.gaussian());
    unit.range_offset.push_back(model.range_offset_sigma * random.gaussian());
  }
  // Drawn after the lasers', so that a unit's per-laser errors do not depend on it.
  unit.elevation_bias_deg =
      model.elevation_bias_mean_deg + model.elevation_bias_sigma_deg * random.gaussian();
  return unit;
}

LidarModel LidarModel::byName(std::string_view name) {
  if (name == "hdl64") return hdl64();
  if (name == "vlp16") return vlp16();
  throw core::Error("unknown LiDAR model '" + std::string(name) + "': expected 'hdl64' or 'vlp16'");
}

}  // namespace dcl::sim
