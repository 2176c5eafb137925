#pragma once

/// Statistics of one spinning-LiDAR sweep that drive registration and place
/// recognition, measured the same way on real scans (a KITTI `.bin`, whose
/// rings are recovered from the order of its points) and simulated ones (whose
/// points carry their ring), so that the simulator can be held to the band of
/// the real sensor:
///
/// - range noise against a local plane fit, by range;
/// - mixed pixels: returns between the two surfaces of a depth edge;
/// - the return rate (one minus dropout) by incidence angle and by intensity;
/// - scattered returns, as vegetation gives (no surface fits them);
/// - the lasers' firing pattern along a ring (steps of half the nominal one,
///   jitter of the step).
///
/// Every statistic is a share or a robust spread, never a count that depends
/// on how much of the scene a scan holds.

#include <array>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/trajectory.hpp>

namespace dcl::eval {

/// Range bands of the plane-fit noise, m: [2, 10), [10, 20), [20, 40).
inline constexpr std::array<double, 4> kNoiseRangeEdges = {2.0, 10.0, 20.0, 40.0};
/// Incidence bins of the return rate, deg: [0, 30), [30, 60), [60, 75), [75, 90].
inline constexpr std::array<double, 5> kIncidenceEdges = {0.0, 30.0, 60.0, 75.0, 90.0};
/// Intensity bins of the return rate: [0, 0.1), [0.1, 0.3), [0.3, 1].
inline constexpr std::array<double, 4> kIntensityEdges = {0.0, 0.1, 0.3, 1.0};

/// The statistics of one sweep.
struct ScanStatistics {
  std::size_t returns = 0;
  /// Robust (1.4826 MAD) spread of a return's distance to the plane of its 12
  /// nearest neighbours, over incidence below 45 deg and divided by the cosine
  /// of the incidence (so: along the beam), m, per kNoiseRangeEdges band.
  std::array<double, kNoiseRangeEdges.size() - 1> plane_noise{};
  /// Of the step edges along a ring (two flat runs of returns more than a metre
  /// and 20 % apart in range, one firing between them), the share whose middle
  /// return lies between the two surfaces, more than a tenth of the step from either.
  double mixed_pixel_share = 0.0;
  /// Returns over returns plus missing firings, by incidence (of the surface of
  /// the return before the gap), within 40 m.
  std::array<double, kIncidenceEdges.size() - 1> return_rate_by_incidence{};
  /// The same by intensity of the return before the gap.
  std::array<double, kIntensityEdges.size() - 1> return_rate_by_intensity{};
  /// Share of the returns within 40 m in each intensity bin (the spread of the
  /// surfaces' reflectivity that the return rate by intensity rests on).
  std::array<double, kIntensityEdges.size() - 1> intensity_share{};
  /// Mean intensity of all the returns.
  double mean_intensity = 0.0;
  /// Share of the returns from 2 to 30 m whose 12 nearest neighbours fit no
  /// surface: their RMS distance to their own plane is above 5 cm.
  double scattered_share = 0.0;
  /// The 90th percentile of those neighbourhoods' RMS distance to their own
  /// plane, m: how deep the returns of the most scattering surfaces (a
  /// crown's foliage) wander along their beams, rather than how many there are.
  double scattered_depth = 0.0;
  /// Share of the steps along a ring shorter than 0.7 of the nominal step.
  double half_step_share = 0.0;
  /// Robust spread of the steps along a ring within 20 % of the nominal one,
  /// relative to it (the firing-time jitter of the lasers).
  double step_jitter = 0.0;
  /// Median azimuth step along a ring, deg.
  double nominal_step_deg = 0.0;
};

/// Measures one sweep in its sensor frame. Its rings come from `scan.ring`
/// when it has them, and otherwise from the order of its points (a ring ends
/// where the azimuth wraps round, as in a KITTI `.bin`). Throws core::Error
/// for a scan of fewer than 1000 returns or with a non-finite point.
ScanStatistics measureScanStatistics(const core::PointCloud& scan);

/// How the vehicle that carries the sensor rocks on its suspension: its pitch
/// and roll against the world's z axis, less their slow part (a centred moving
/// mean over 2 s: the road's grade and camber), so that what remains is the
/// body's answer to braking, accelerating and turning.
struct AttitudeStatistics {
  double pitch_sigma_deg = 0.0;  ///< robust (1.4826 MAD) spread of the fast pitch
  double roll_sigma_deg = 0.0;   ///< the same of the roll
  double pitch_p99_deg = 0.0;    ///< 99th percentile of |fast pitch|
  double roll_p99_deg = 0.0;     ///< 99th percentile of |fast roll|
};

/// The attitude statistics of a sensor's trajectory T_world_sensor (x forward,
/// z up). Throws core::Error for fewer than 50 poses.
AttitudeStatistics measureAttitude(const core::Trajectory& T_world_sensor);

/// A closed interval of one statistic over several scans.
struct StatisticBand {
  double lo = 0.0;
  double hi = 0.0;
  [[nodiscard]] bool contains(double v, double tolerance = 0.0) const {
    return v >= lo - tolerance && v <= hi + tolerance;
  }
};

/// One named statistic (for tables): its name, how it reads from
/// ScanStatistics, and how far outside the band of a handful of real scans a
/// value still counts as real (one street of KITTI 00 is not every street).
struct StatisticRow {
  std::string name;  ///< e.g. "plane noise 10-20 m (m)"
  double (*value)(const ScanStatistics&);
  double tolerance = 0.0;
};

/// Every statistic of ScanStatistics but `returns`, in the order of its fields.
std::span<const StatisticRow> statisticRows();

/// The band of `row` over `scans` (min to max). Throws core::Error when empty.
StatisticBand bandOf(const StatisticRow& row, std::span<const ScanStatistics> scans);

}  // namespace dcl::eval
