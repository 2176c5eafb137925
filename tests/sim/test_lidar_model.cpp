#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/sim/lidar_model.hpp>

namespace dcl::sim {
namespace {

TEST(LidarModel, Hdl64HasKittiGeometry) {
  const LidarModel m = LidarModel::hdl64();
  EXPECT_EQ(m.name, "hdl64");
  ASSERT_EQ(m.elevations_deg.size(), 64u);
  EXPECT_NEAR(m.elevations_deg.back(), 2.0, 1e-9);     // top beam
  EXPECT_NEAR(m.elevations_deg.front(), -24.8, 1e-9);  // bottom beam
  EXPECT_TRUE(std::is_sorted(m.elevations_deg.begin(), m.elevations_deg.end()));
  EXPECT_EQ(m.columns, 2160);
  EXPECT_DOUBLE_EQ(m.rate_hz, 10.0);
  EXPECT_DOUBLE_EQ(m.max_range, 120.0);
  // Range noise from about 1.5 cm near to 3.5 cm far, as KITTI's sweeps show
  // against local planes (test_realism.cpp holds the scans to them).
  const auto sigma_at = [&](double r) {
    return std::min(m.range_noise_sigma + m.range_noise_per_m * r, m.range_noise_max);
  };
  EXPECT_GT(sigma_at(5.0), 0.01);
  EXPECT_LT(sigma_at(5.0), 0.02);
  EXPECT_GT(sigma_at(40.0), 2.0 * sigma_at(5.0) - 1e-9);
  EXPECT_LE(sigma_at(100.0), 0.04);
  EXPECT_GT(m.dropout, 0.0);
  EXPECT_LT(m.dropout, 0.1);
  EXPECT_GT(m.dark_dropout, m.dropout);  // weak echoes fade first
  EXPECT_DOUBLE_EQ(m.mount_height, 1.73);
  EXPECT_EQ(m.raysPerScan(), 138240u);
  EXPECT_DOUBLE_EQ(m.sweepDuration(), 0.1);
}

// KITTI's rings step 0.179 deg from firing to firing, and one step in 6.8
// is half that (bench sensor's "half steps along a ring": 14.7-15.2 %).
TEST(LidarModel, Hdl64FiresAHalfStepAboutOneStepInSeven) {
  const LidarModel m = LidarModel::hdl64();
  EXPECT_DOUBLE_EQ(m.columnPhase(0), 0.0);
  std::vector<double> steps;
  for (int c = 1; c < m.columns; ++c)
    steps.push_back(360.0 * (m.columnPhase(c) - m.columnPhase(c - 1)));
  ASSERT_LT(m.columnPhase(m.columns - 1), 1.0);
  const double full = *std::max_element(steps.begin(), steps.end());
  EXPECT_NEAR(full, 0.179, 0.002);
  std::size_t halves = 0;
  for (const double step : steps) {
    EXPECT_TRUE(std::abs(step - full) < 1e-9 || std::abs(step - 0.5 * full) < 1e-9) << step;
    halves += step < 0.75 * full;
  }
  EXPECT_NEAR(static_cast<double>(halves) / static_cast<double>(steps.size()), 1.0 / 6.8, 0.005);
  // The VLP-16 (no real sweep to hold it to) fires evenly.
  const LidarModel v = LidarModel::vlp16();
  EXPECT_DOUBLE_EQ(v.columnPhase(900), 0.5);
}

TEST(LidarModel, Hdl64BlocksAreDenseAboveAndSparseBelow) {
  const auto& e = LidarModel::hdl64().elevations_deg;
  // Lower block: rings 0-31, about 1/2 deg apart; upper block: rings 32-63, 1/3 deg.
  for (int r = 1; r < 32; ++r) EXPECT_NEAR(e[r] - e[r - 1], 0.515, 0.01) << r;
  for (int r = 33; r < 64; ++r) EXPECT_NEAR(e[r] - e[r - 1], 1.0 / 3.0, 1e-9) << r;
  EXPECT_NEAR(e[31], -8.83, 1e-9);
  EXPECT_NEAR(e[32], 2.0 - 31.0 / 3.0, 1e-9);
}

TEST(LidarModel, Hdl64SitsAboveItsCarsBody) {
  const LidarModel m = LidarModel::hdl64();
  ASSERT_TRUE(m.ego_body.has_value());
  EXPECT_FALSE(m.ego_body->contains(Eigen::Vector3d::Zero()));
  EXPECT_LT(m.ego_body->max().z(), 0.0);                        // below the sensor
  EXPECT_GT(m.ego_body->min().z(), -m.mount_height);            // above the road
  EXPECT_GT(m.ego_body->sizes().x(), m.ego_body->sizes().y());  // longer than wide
  EXPECT_FALSE(LidarModel::vlp16().ego_body.has_value());
}

TEST(LidarModel, Vlp16Has16BeamsTwoDegreesApart) {
  const LidarModel m = LidarModel::vlp16();
  EXPECT_EQ(m.name, "vlp16");
  ASSERT_EQ(m.elevations_deg.size(), 16u);
  for (std::size_t r = 0; r < 16; ++r)
    EXPECT_NEAR(m.elevations_deg[r], -15.0 + 2.0 * static_cast<double>(r), 1e-12);
  EXPECT_EQ(m.columns, 1800);
  EXPECT_DOUBLE_EQ(m.rate_hz, 10.0);
  EXPECT_DOUBLE_EQ(m.max_range, 100.0);
  EXPECT_LT(m.mount_height, 1.73);
  EXPECT_EQ(m.raysPerScan(), 28800u);
}

TEST(BeamCalibration, EachUnitIsDrawnFromItsSeedWithTheModelsSpread) {
  const LidarModel m = LidarModel::vlp16();
  ASSERT_GT(m.elevation_error_sigma_deg, 0.0);
  ASSERT_GT(m.range_offset_sigma, 0.0);
  const BeamCalibration unit = BeamCalibration::draw(m, 7);
  ASSERT_EQ(unit.elevation_error_deg.size(), 16u);
  ASSERT_EQ(unit.range_offset.size(), 16u);
  EXPECT_EQ(BeamCalibration::draw(m, 7).elevation_error_deg, unit.elevation_error_deg);
  EXPECT_NE(BeamCalibration::draw(m, 8).elevation_error_deg, unit.elevation_error_deg);
  // Over many units, each laser's errors spread as the model says, around zero.
  double elevation = 0.0, range = 0.0, mean = 0.0;
  std::size_t n = 0;
  for (std::uint64_t seed = 0; seed < 500; ++seed) {
    const BeamCalibration u = BeamCalibration::draw(m, seed);
    for (std::size_t r = 0; r < 16; ++r, ++n) {
      elevation += u.elevation_error_deg[r] * u.elevation_error_deg[r];
      range += u.range_offset[r] * u.range_offset[r];
      mean += u.elevation_error_deg[r];
    }
  }
  EXPECT_NEAR(std::sqrt(elevation / n), m.elevation_error_sigma_deg,
              0.05 * m.elevation_error_sigma_deg);
  EXPECT_NEAR(std::sqrt(range / n), m.range_offset_sigma, 0.05 * m.range_offset_sigma);
  EXPECT_NEAR(mean / n, 0.0, 0.1 * m.elevation_error_sigma_deg);
  // A model without calibration error makes perfect units.
  LidarModel perfect = m;
  perfect.elevation_error_sigma_deg = 0.0;
  perfect.range_offset_sigma = 0.0;
  perfect.elevation_bias_sigma_deg = 0.0;
  EXPECT_TRUE(BeamCalibration::draw(perfect, 7).empty());
}

TEST(BeamCalibration, AUnitsLasersShareOneElevationBias) {
  // The HDL-64 as on KITTI carries KITTI's unit-wide error: its scans need
  // every elevation raised by about 0.2 deg.
  const LidarModel hdl64 = LidarModel::hdl64();
  for (const std::uint64_t seed : {1, 2, 3}) {
    EXPECT_NEAR(BeamCalibration::draw(hdl64, seed).elevation_bias_deg, 0.205, 1e-12);
  }
  // The VLP-16, with no real sweep to measure it on, has none; a model given
  // a spread draws each unit's own, either way, and the per-laser errors do
  // not change with it.
  EXPECT_EQ(BeamCalibration::draw(LidarModel::vlp16(), 7).elevation_bias_deg, 0.0);
  LidarModel vlp16 = LidarModel::vlp16();
  vlp16.elevation_bias_sigma_deg = 0.2;
  double square = 0.0;
  int positive = 0;
  constexpr int kUnits = 500;
  for (int seed = 0; seed < kUnits; ++seed) {
    const double bias = BeamCalibration::draw(vlp16, seed).elevation_bias_deg;
    square += bias * bias;
    positive += bias > 0.0 ? 1 : 0;
  }
  EXPECT_NEAR(std::sqrt(square / kUnits), vlp16.elevation_bias_sigma_deg,
              0.1 * vlp16.elevation_bias_sigma_deg);
  EXPECT_GT(positive, kUnits / 3);
  EXPECT_LT(positive, 2 * kUnits / 3);
  LidarModel unbiased = vlp16;
  unbiased.elevation_bias_sigma_deg = 0.0;
  EXPECT_EQ(BeamCalibration::draw(unbiased, 7).elevation_error_deg,
            BeamCalibration::draw(vlp16, 7).elevation_error_deg);
  EXPECT_EQ(BeamCalibration::draw(unbiased, 7).elevation_bias_deg, 0.0);
  // A model with only the bias still makes an imperfect unit.
  LidarModel only_bias = hdl64;
  only_bias.elevation_error_sigma_deg = 0.0;
  only_bias.range_offset_sigma = 0.0;
  EXPECT_FALSE(BeamCalibration::draw(only_bias, 7).empty());
}

TEST(LidarModel, ByNameFindsBothAndNamesTheChoicesOtherwise) {
  EXPECT_EQ(LidarModel::byName("hdl64").elevations_deg, LidarModel::hdl64().elevations_deg);
  EXPECT_EQ(LidarModel::byName("vlp16").columns, 1800);
  try {
    (void)LidarModel::byName("os1-128");
    FAIL() << "no error for an unknown model";
  } catch (const core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("os1-128"), std::string::npos) << what;
    EXPECT_NE(what.find("hdl64"), std::string::npos) << what;
    EXPECT_NE(what.find("vlp16"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace dcl::sim
