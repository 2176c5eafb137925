#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::core {
namespace {

PointCloud threePoints(bool with_intensity) {
  PointCloud c;
  c.points = {{1, 0, 0}, {0, 2, 0}, {0, 0, 3}};
  if (with_intensity) c.intensity = {0.1f, 0.2f, 0.3f};
  return c;
}

TEST(PointCloud, ChannelsAreOptionalButMustFit) {
  PointCloud c = threePoints(true);
  EXPECT_TRUE(c.consistent());
  EXPECT_TRUE(c.hasIntensity());
  EXPECT_FALSE(c.hasTime());
  c.ring = {1, 2};
  EXPECT_FALSE(c.consistent());
}

TEST(PointCloud, AppendKeepsChannelsAligned) {
  PointCloud a = threePoints(true);
  a.append(threePoints(true));
  EXPECT_EQ(a.size(), 6u);
  EXPECT_EQ(a.intensity.size(), 6u);
  EXPECT_FLOAT_EQ(a.intensity[4], 0.2f);
  PointCloud empty;
  empty.append(a);
  EXPECT_EQ(empty.size(), 6u);
}

TEST(PointCloud, AppendRefusesMismatchedChannels) {
  PointCloud a = threePoints(true);
  EXPECT_THROW(a.append(threePoints(false)), Error);
}

TEST(PointCloud, TransformMapsPoints) {
  const Eigen::Isometry3d T = makePose2d(1.0, 0.0, M_PI / 2);
  const PointCloud moved = transformed(threePoints(false), T);
  EXPECT_NEAR(moved.points[0].x(), 1.0f, 1e-6f);
  EXPECT_NEAR(moved.points[0].y(), 1.0f, 1e-6f);
  EXPECT_NEAR(moved.points[1].x(), -1.0f, 1e-6f);
  EXPECT_NEAR(moved.points[2].z(), 3.0f, 1e-6f);
}

}  // namespace
}  // namespace dcl::core
