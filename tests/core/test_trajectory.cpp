#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/core/trajectory.hpp>

namespace dcl::core {
namespace {

Trajectory square() {
  Trajectory t;
  t.push_back(0.0, makePose2d(0, 0, 0));
  t.push_back(1.0, makePose2d(1, 0, M_PI / 2));
  t.push_back(2.0, makePose2d(1, 1, M_PI));
  t.push_back(3.0, makePose2d(0, 1, -M_PI / 2));
  return t;
}

TEST(Trajectory, LengthAndDistances) {
  const Trajectory t = square();
  EXPECT_DOUBLE_EQ(t.length(), 3.0);
  const auto d = t.distances();
  ASSERT_EQ(d.size(), 4u);
  EXPECT_DOUBLE_EQ(d[2], 2.0);
  EXPECT_TRUE(t.isSorted());
  EXPECT_DOUBLE_EQ(Trajectory().length(), 0.0);
}

TEST(Trajectory, InterpolatesInsideAndRefusesOutside) {
  const Trajectory t = square();
  const auto mid = t.at(0.5);
  ASSERT_TRUE(mid.has_value());
  EXPECT_TRUE(mid->translation().isApprox(Eigen::Vector3d(0.5, 0, 0)));
  EXPECT_NEAR(rotationAngle(mid->linear()), M_PI / 4, 1e-12);
  EXPECT_TRUE(t.at(2.0)->isApprox(t.pose(2)));
  EXPECT_TRUE(t.at(0.0)->isApprox(t.pose(0)));
  EXPECT_TRUE(t.at(3.0)->isApprox(t.pose(3)));
  EXPECT_FALSE(t.at(-0.1).has_value());
  EXPECT_FALSE(t.at(3.1).has_value());
}

TEST(Trajectory, ChangesOfFrame) {
  Trajectory t = square();
  t.transformWorld(makePose2d(10, 0, 0));
  EXPECT_TRUE(t.pose(1).translation().isApprox(Eigen::Vector3d(11, 0, 0)));
  t.transformBody(makePose2d(1, 0, 0));  // a sensor 1 m ahead of the body
  EXPECT_TRUE(t.pose(1).translation().isApprox(Eigen::Vector3d(11, 1, 0)));
}

TEST(Trajectory, MismatchedSizesAreAnError) {
  EXPECT_THROW(Trajectory({0.0, 1.0}, {Eigen::Isometry3d::Identity()}), Error);
}

}  // namespace
}  // namespace dcl::core
