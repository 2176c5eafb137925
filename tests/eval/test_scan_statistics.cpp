// Statistics of LiDAR sweeps (eval/scan_statistics.hpp): each one recovers
// what a sweep of known noise, dropout, edges and firing pattern was made
// with, and the real KITTI scans read as an HDL-64E at 10 Hz.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/scan_statistics.hpp>
#include <dcl/io/kitti_scan.hpp>

namespace dcl::eval {
namespace {

/// How the synthetic sweep is made.
struct SweepRecipe {
  double noise = 0.02;     ///< m, Gaussian range noise
  double dropout = 0.0;    ///< share of firings that return nothing, at random
  bool mixed = false;      ///< the firing at each edge of the pillar returns between the surfaces
  double foliage = 0.0;    ///< m, mean (exponential) depth the pillar's returns lie behind it
  bool with_rings = true;  ///< store the ring (otherwise rely on the order, as a KITTI .bin)
  unsigned seed = 1;
};

constexpr int kRings = 32;
constexpr int kColumns = 1800;

/// A sensor 1.7 m above the floor of a 24 x 20 m hall, a pillar 6 m ahead
/// that covers 6.1 deg of azimuth. Rings are stored one after the other, each
/// going round in increasing azimuth from -pi, as a KITTI .bin stores them.
core::PointCloud syntheticSweep(const SweepRecipe& recipe) {
  std::mt19937 rng(recipe.seed);
  std::normal_distribution<double> gauss(0.0, recipe.noise);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  core::PointCloud cloud;
  for (int r = 0; r < kRings; ++r) {
    const double elevation = (-20.0 + 25.0 * r / (kRings - 1)) * M_PI / 180.0;
    for (int c = 0; c < kColumns; ++c) {
      const double azimuth = -M_PI + 2.0 * M_PI * (c + 0.5) / kColumns;
      const Eigen::Vector3d d(std::cos(elevation) * std::cos(azimuth),
                              std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
      // Walls at x = -10, 14 and y = -8, 12, floor at z = -1.7, ceiling at 6.
      double range = 1e9;
      const auto plane = [&](double along, double at) {
        if (along * at > 0) range = std::min(range, at / along);
      };
      plane(d.x(), d.x() > 0 ? 14.0 : -10.0);
      plane(d.y(), d.y() > 0 ? 12.0 : -8.0);
      plane(d.z(), d.z() > 0 ? 6.0 : -1.7);
      const double pillar = 3.05 * M_PI / 180.0;  // edges between column centres
      if (std::abs(azimuth) < pillar && d.z() * 6.0 / d.x() > -1.7)
        range = 6.0 / d.x() -
                (recipe.foliage > 0.0 ? recipe.foliage * std::log(1.0 - uniform(rng)) : 0.0);
      if (recipe.mixed && std::abs(std::abs(azimuth) - pillar) < M_PI / kColumns)
        range = 0.5 * (6.0 / d.x() + range);
      if (uniform(rng) < recipe.dropout) continue;
      range += gauss(rng);
      cloud.points.push_back((d * range).cast<float>());
      cloud.intensity.push_back(0.2f);
      if (recipe.with_rings) cloud.ring.push_back(static_cast<std::uint16_t>(r));
    }
  }
  return cloud;
}

TEST(ScanStatistics, PlaneNoiseIsTheRangeNoiseTheSweepWasMadeWith) {
  for (const double noise : {0.01, 0.03}) {
    const ScanStatistics s = measureScanStatistics(syntheticSweep({.noise = noise}));
    for (int band = 0; band < 2; ++band) {
      SCOPED_TRACE(::testing::Message() << "noise " << noise << " m, range band " << band);
      EXPECT_NEAR(s.plane_noise[band], noise, 0.2 * noise);
    }
  }
}

TEST(ScanStatistics, ReturnRateIsOneMinusTheDropout) {
  for (const double dropout : {0.0, 0.05, 0.2}) {
    const ScanStatistics s = measureScanStatistics(syntheticSweep({.dropout = dropout}));
    SCOPED_TRACE(::testing::Message() << "dropout " << dropout);
    EXPECT_NEAR(s.return_rate_by_intensity[1], 1.0 - dropout, 0.02);
    EXPECT_NEAR(s.return_rate_by_incidence[0], 1.0 - dropout, 0.03);
    // Isolated gaps of a missing firing are not half steps.
    EXPECT_LT(s.half_step_share, 0.005);
  }
}

TEST(ScanStatistics, MixedPixelsAreFoundAtDepthEdgesOnly) {
  const ScanStatistics clean = measureScanStatistics(syntheticSweep({.noise = 0.01}));
  const ScanStatistics mixed =
      measureScanStatistics(syntheticSweep({.noise = 0.01, .mixed = true}));
  EXPECT_LT(clean.mixed_pixel_share, 0.05);
  EXPECT_GT(mixed.mixed_pixel_share, 0.9);
  // Flat walls and floor: nothing scattered, whatever the edges.
  EXPECT_LT(clean.scattered_share, 0.03);
}

TEST(ScanStatistics, ScatteredReturnsSpreadAsDeepAsBeamsGoIntoFoliage) {
  const ScanStatistics solid = measureScanStatistics(syntheticSweep({.noise = 0.01}));
  const ScanStatistics shallow =
      measureScanStatistics(syntheticSweep({.noise = 0.01, .foliage = 0.1}));
  const ScanStatistics deep =
      measureScanStatistics(syntheticSweep({.noise = 0.01, .foliage = 0.4}));
  // The pillar is about a seventieth of the returns. A return's nearest
  // neighbours are those at its own depth, so a shallow crown scatters only
  // some of them; deeper ones scatter more, and further.
  EXPECT_LT(solid.scattered_share, 0.002);
  EXPECT_GT(shallow.scattered_share, 1.5 * solid.scattered_share);
  EXPECT_GT(deep.scattered_share, 3.0 * shallow.scattered_share);
  EXPECT_GT(shallow.scattered_depth, 0.05);  // above the threshold that makes them scattered
  EXPECT_GT(deep.scattered_depth, shallow.scattered_depth + 0.02);
}

TEST(ScanStatistics, RingsFromThePointOrderGiveTheSameStatistics) {
  const ScanStatistics ringed = measureScanStatistics(syntheticSweep({.dropout = 0.05}));
  const ScanStatistics ordered =
      measureScanStatistics(syntheticSweep({.dropout = 0.05, .with_rings = false}));
  EXPECT_DOUBLE_EQ(ringed.nominal_step_deg, ordered.nominal_step_deg);
  EXPECT_NEAR(ringed.return_rate_by_intensity[1], ordered.return_rate_by_intensity[1], 1e-3);
  EXPECT_NEAR(ringed.mixed_pixel_share, ordered.mixed_pixel_share, 1e-9);
  EXPECT_NEAR(ringed.nominal_step_deg, 0.2, 1e-3);
}

TEST(ScanStatistics, RefusesANonFinitePointNamingIt) {
  core::PointCloud organised = syntheticSweep({});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  organised.points[97] = Eigen::Vector3f(nan, nan, nan);
  try {
    (void)measureScanStatistics(organised);
    FAIL() << "a NaN point was measured";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("point 97"), std::string::npos) << e.what();
  }
}

TEST(ScanStatistics, RefusesASweepTooSmallToMeasure) {
  core::PointCloud few;
  few.points.assign(10, Eigen::Vector3f(5.0f, 0.0f, 0.0f));
  EXPECT_THROW((void)measureScanStatistics(few), core::Error);
}

// A real sweep of KITTI 00 reads as the HDL-64E S2 at 10 Hz that took it: an
// azimuth step near 0.18 deg, about 2 cm of range noise on near surfaces, and
// almost every firing at a surface within 40 m returning.
TEST(ScanStatistics, RealKittiSweepReadsAsAnHdl64) {
  const auto file =
      std::filesystem::path(DCL_DATA_DIR) / "lidar_scans/kitti_00/velodyne/000000.bin";
  const ScanStatistics s = measureScanStatistics(io::readKittiScan(file.string()));
  EXPECT_NEAR(s.nominal_step_deg, 0.18, 0.01);
  EXPECT_GT(s.plane_noise[0], 0.005);
  EXPECT_LT(s.plane_noise[0], 0.05);
  EXPECT_GT(s.return_rate_by_incidence[0], 0.9);
}

// A car on a road climbing at 5 % with a slow camber change, its body rocking
// by 0.3 deg of pitch at 1.5 Hz: the attitude keeps the rocking, not the road.
TEST(AttitudeStatistics, KeepTheBodysRockingAndLeaveTheRoad) {
  std::vector<double> stamps;
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < 600; ++i) {
    const double t = 0.1 * i;
    const double grade = std::atan(0.05), camber = 0.02 * std::sin(t / 20.0);
    const double rocking = 0.3 * M_PI / 180.0 * std::sin(2.0 * M_PI * 1.5 * t);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = (Eigen::AngleAxisd(-(grade + rocking), Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(camber, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
    pose.translation() = Eigen::Vector3d(10.0 * t, 0.0, 0.5 * t);
    stamps.push_back(t);
    poses.push_back(pose);
  }
  const AttitudeStatistics a = measureAttitude(core::Trajectory(stamps, poses));
  // |0.3 sin| has median 0.3 sin(pi/4) = 0.212 deg; robust sigma 1.4826 times that.
  EXPECT_NEAR(a.pitch_sigma_deg, 1.4826 * 0.212, 0.04);
  EXPECT_NEAR(a.pitch_p99_deg, 0.3, 0.03);
  EXPECT_LT(a.roll_sigma_deg, 0.01);
  EXPECT_THROW((void)measureAttitude(core::Trajectory({0.0}, {Eigen::Isometry3d::Identity()})),
               core::Error);
}

}  // namespace
}  // namespace dcl::eval
