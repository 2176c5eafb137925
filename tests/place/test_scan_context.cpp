#include <cmath>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/place/scan_context.hpp>

#include "descriptor_test_data.hpp"

namespace dcl::place {
namespace {

TEST(ScanContext, KeepsTheHighestPointPerBin) {
  core::PointCloud c;
  c.points = {{10.0F, 0.5F, -1.0F}, {10.5F, 0.2F, 1.5F}, {0.0F, 30.0F, 0.0F}, {100.0F, 0.0F, 3.0F}};
  const ScanContextDescriptor d = describeScanContext(c);
  ASSERT_EQ(d.rings, 20);
  ASSERT_EQ(d.sectors, 60);
  EXPECT_FLOAT_EQ(d.at(2, 0), 3.5F);   // 10 m / 4 m rings, max(z) + 2 m
  EXPECT_FLOAT_EQ(d.at(7, 15), 2.0F);  // 90 deg / 6 deg
  float total = 0.0F;
  for (float v : d.cells) total += v;
  EXPECT_FLOAT_EQ(total, 5.5F);  // the point beyond 80 m is dropped
  EXPECT_FLOAT_EQ(d.ring_key[2], 3.5F / 60.0F);
}

TEST(ScanContext, FindsTheYawOfRotatedCopies) {
  const core::PointCloud scan = test::kittiScan(0);
  const ScanContextDescriptor query = describeScanContext(scan);
  for (double deg : {0.0, 30.0, -96.0, 174.0}) {
    const ScanContextDescriptor rotated =
        describeScanContext(test::rotatedZ(scan, test::radians(deg + 3.0)));
    const Match m = matchScanContext(query, rotated);
    // Turned half a sector off the grid: the yaw is within half a sector.
    EXPECT_NEAR(std::remainder(test::degrees(m.yaw_rad) + deg + 3.0, 360.0), 0.0, 3.1) << deg;
    EXPECT_LT(m.distance, 0.15) << deg;
    EXPECT_EQ(m.reversed, std::abs(deg) > 90.0);
    for (int r = 0; r < 20; ++r) EXPECT_NEAR(query.ring_key[r], rotated.ring_key[r], 0.1) << r;
  }
}

TEST(ScanContext, SeparatesConsecutiveFramesFromDifferentPlaces) {
  const auto d = [](int f) { return describeScanContext(test::kittiScan(f)); };
  const ScanContextDescriptor a = d(0), b = d(1), far = d(198);
  const double same = matchScanContext(a, b).distance;
  const double other = matchScanContext(a, far).distance;
  EXPECT_LT(same, 0.2);
  EXPECT_GT(other, same + 0.15);
  EXPECT_NEAR(scanContextDistance(a, a, 0), 0.0, 1e-9);
}

TEST(ScanContext, WorksBehindTheInterface) {
  DescriptorConfig config;
  config.kind = "scancontext";
  const std::unique_ptr<Descriptor> sc = makeDescriptor(config);
  EXPECT_EQ(sc->kind(), DescriptorKind::kScanContext);
  EXPECT_EQ(sc->keySize(), 20U);
  const auto a = sc->describe(test::kittiScan(94));
  const auto b = sc->describe(test::kittiScan(95));
  EXPECT_LT(sc->match(*a, *b).distance, 0.2);
  EXPECT_THROW((void)sc->match(*a, *makeDescriptor()->describe(test::kittiScan(94))), core::Error);
  ScanContextConfig bad;
  bad.sectors = 0;
  EXPECT_THROW(ScanContext{bad}, core::Error);
}

}  // namespace
}  // namespace dcl::place
