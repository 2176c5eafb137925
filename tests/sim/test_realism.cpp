// Realism of simulated HDL-64 scans in the city world, against the real KITTI
// 00 scans in the shared data: number of returns, share of ground returns and
// the range histogram.
//
// The band of each statistic is measured here from the ten real scans (min to
// max over the files), then widened by a stated tolerance, because one street
// of KITTI 00 is not every street: kTolerance on the ground share and on each
// range bin's share, kSparseTolerance on the sparse far bins. The lead measured
// on these files: 121.6k-124.7k returns, ground share 0.46-0.60, range shares
// [0,5) 0.06-0.12, [5,10) 0.42-0.53, [10,20) 0.26-0.33, [20,40) 0.08-0.14,
// [40,80) 0.018-0.042, nothing past 80 m. The number of returns is held to the
// issue's 100k-130k.
//
// The second test holds the sensor's imperfections (eval/scan_statistics.hpp:
// range noise against a local plane by range, mixed pixels, return rate by
// incidence and intensity, the spread of intensities, firing jitter) to the
// band of the same real scans, widened by each statistic's stated tolerance.

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/eval/scan_statistics.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/sim/scan_simulator.hpp>
#include <dcl/sim/world_gen.hpp>

#include "world_test_util.hpp"

namespace dcl::sim {
namespace {

namespace fs = std::filesystem;

/// Range bin edges, m; the last bin is everything from 80 m on.
constexpr std::array<double, 6> kEdges = {0, 5, 10, 20, 40, 80};
constexpr std::size_t kBins = kEdges.size();
/// Widening of the real band of the ground share and of the near range bins.
constexpr double kTolerance = 0.05;
/// Widening of the real band of the sparse bins from 40 m on.
constexpr double kSparseTolerance = 0.015;
/// Below this height in the sensor frame a return counts as ground (the sensor rides 1.73 m up).
constexpr float kGroundZ = -1.4f;

/// The statistics the test compares.
struct ScanStats {
  double returns = 0;
  double ground_share = 0;
  std::array<double, kBins> range_share{};
  double mean_intensity = 0;
};

ScanStats measure(const core::PointCloud& scan) {
  ScanStats s;
  s.returns = static_cast<double>(scan.size());
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const double r = scan.points[i].norm();
    const auto bin = std::upper_bound(kEdges.begin(), kEdges.end(), r) - kEdges.begin() - 1;
    s.range_share[static_cast<std::size_t>(bin)] += 1.0;
    s.ground_share += scan.points[i].z() < kGroundZ;
    if (scan.hasIntensity()) s.mean_intensity += scan.intensity[i];
  }
  for (double& share : s.range_share) share /= s.returns;
  s.ground_share /= s.returns;
  s.mean_intensity /= s.returns;
  return s;
}

/// A closed interval.
struct Band {
  double lo = 1e300;
  double hi = -1e300;
  void extend(double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  [[nodiscard]] Band widened(double by) const { return {lo - by, hi + by}; }
  [[nodiscard]] bool contains(double v) const { return v >= lo && v <= hi; }
};

/// The bands of the real KITTI scans, widened by the tolerances.
struct RealBands {
  std::size_t files = 0;
  Band ground;
  std::array<Band, kBins> range;
  Band intensity;
};

RealBands measureRealScans() {
  RealBands bands;
  std::vector<fs::path> files;
  for (const auto& e :
       fs::directory_iterator(fs::path(DCL_DATA_DIR) / "lidar_scans/kitti_00/velodyne"))
    if (e.path().extension() == ".bin") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& file : files) {
    const ScanStats s = measure(io::readKittiScan(file.string()));
    bands.ground.extend(s.ground_share);
    for (std::size_t b = 0; b < kBins; ++b) bands.range[b].extend(s.range_share[b]);
    bands.intensity.extend(s.mean_intensity);
  }
  bands.files = files.size();
  bands.ground = bands.ground.widened(kTolerance);
  for (std::size_t b = 0; b < kBins; ++b)
    bands.range[b] = bands.range[b].widened(kEdges[b] >= 40 ? kSparseTolerance : kTolerance);
  return bands;
}

std::string describe(const Band& band) {
  std::ostringstream out;  // not string concatenation: GCC 12 warns falsely on it (-Wrestrict)
  out << "[" << band.lo << ", " << band.hi << "]";
  return out.str();
}

TEST(Realism, CityHdl64ScansMatchRealKittiScans) {
  const RealBands real = measureRealScans();
  ASSERT_EQ(real.files, 10u) << "the shared data holds ten KITTI 00 scans";
  // KITTI 05's first 300 m of ground truth, in the LiDAR frame, with a city around it.
  const std::vector<core::Trajectory> routes = {test::kittiExcerpt(300)};
  const World world = generateCityWorld({routes, test::kMount, 5});
  const ScanSimulator simulator(world, LidarModel::hdl64());
  const auto distances = routes[0].distances();
  for (const double at : {40.0, 90.0, 140.0, 190.0, 240.0}) {
    const auto i = static_cast<std::size_t>(
        std::lower_bound(distances.begin(), distances.end(), at) - distances.begin());
    const ScanStats s = measure(simulator.scan(routes[0], routes[0].stamp(i), 100 + i));
    SCOPED_TRACE(::testing::Message() << "scan at " << at << " m along the route");
    EXPECT_GE(s.returns, 100000);
    EXPECT_LE(s.returns, 130000);
    EXPECT_TRUE(real.ground.contains(s.ground_share))
        << "ground share " << s.ground_share << " outside " << describe(real.ground);
    for (std::size_t b = 0; b < kBins; ++b)
      EXPECT_TRUE(real.range[b].contains(s.range_share[b]))
          << "range bin from " << kEdges[b] << " m: share " << s.range_share[b] << " outside "
          << describe(real.range[b]);
    std::printf(
        "scan at %3.0f m: %6.0f returns, ground %.3f, ranges %.3f %.3f %.3f %.3f %.3f %.3f, "
        "intensity %.3f\n",
        at, s.returns, s.ground_share, s.range_share[0], s.range_share[1], s.range_share[2],
        s.range_share[3], s.range_share[4], s.range_share[5], s.mean_intensity);
  }
}

/// The statistics of the ten real KITTI 00 scans.
std::vector<eval::ScanStatistics> realSweepStatistics() {
  std::vector<eval::ScanStatistics> stats;
  for (const auto& e :
       fs::directory_iterator(fs::path(DCL_DATA_DIR) / "lidar_scans/kitti_00/velodyne"))
    if (e.path().extension() == ".bin")
      stats.push_back(eval::measureScanStatistics(io::readKittiScan(e.path().string())));
  return stats;
}

TEST(Realism, CityHdl64SensorImperfectionsMatchRealKittiScans) {
  const auto real = realSweepStatistics();
  ASSERT_EQ(real.size(), 10u);
  const std::vector<core::Trajectory> routes = {test::kittiExcerpt(300)};
  const World world = generateCityWorld({routes, test::kMount, 5});
  const ScanSimulator simulator(world, LidarModel::hdl64());
  const BeamCalibration unit = BeamCalibration::draw(simulator.model(), 7);
  const auto distances = routes[0].distances();
  std::vector<eval::ScanStatistics> simulated;
  for (const double at : {40.0, 90.0, 140.0, 190.0, 240.0}) {
    const auto i = static_cast<std::size_t>(
        std::lower_bound(distances.begin(), distances.end(), at) - distances.begin());
    simulated.push_back(
        eval::measureScanStatistics(simulator.scan(routes[0], routes[0].stamp(i), 100 + i, unit)));
  }
  for (const auto& row : eval::statisticRows()) {
    const eval::StatisticBand band = eval::bandOf(row, real);
    std::vector<double> values;
    for (const auto& s : simulated) values.push_back(row.value(s));
    std::sort(values.begin(), values.end());
    const double median = values[values.size() / 2];
    std::printf("%-34s real %.4f-%.4f  simulated median %.4f\n", row.name.c_str(), band.lo, band.hi,
                median);
    EXPECT_TRUE(band.contains(median, row.tolerance))
        << row.name << ": simulated median " << median << " outside the real band [" << band.lo
        << ", " << band.hi << "] +/- " << row.tolerance;
  }
}

}  // namespace
}  // namespace dcl::sim
