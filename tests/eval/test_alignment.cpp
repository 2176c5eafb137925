#include <random>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/alignment.hpp>

#include "test_support.hpp"

namespace dcl::eval {
namespace {

Eigen::Matrix3Xd randomPoints(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) p.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return p;
}

Sim3 randomSim3(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Sim3 S;
  S.R = core::expSO3(Eigen::Vector3d(u(rng), u(rng), u(rng)) * 2.5);
  S.t = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 50.0;
  S.s = 0.2 + 3.0 * (u(rng) + 1.0);
  return S;
}

Eigen::Matrix3Xd apply(const Sim3& S, const Eigen::Matrix3Xd& points) {
  return ((S.s * S.R * points).colwise() + S.t).eval();
}

TEST(Alignment, UmeyamaRecoversRandomSim3Exactly) {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 20; ++trial) {
    const Sim3 truth = randomSim3(rng);
    const Eigen::Matrix3Xd source = randomPoints(rng, 3 + trial * 7);
    const Sim3 found = umeyamaAlignment(source, apply(truth, source), true);
    EXPECT_TRUE(found.R.isApprox(truth.R, 1e-9)) << trial;
    EXPECT_NEAR((found.t - truth.t).norm(), 0.0, 1e-9) << trial;
    EXPECT_NEAR(found.s, truth.s, 1e-9) << trial;
    EXPECT_NEAR(found.R.determinant(), 1.0, 1e-12);
  }
}

TEST(Alignment, UmeyamaWithoutScaleRecoversRigidMotion) {
  std::mt19937 rng(7);
  Sim3 truth = randomSim3(rng);
  truth.s = 1.0;
  const Eigen::Matrix3Xd source = randomPoints(rng, 50);
  const Sim3 found = umeyamaAlignment(source, apply(truth, source), false);
  EXPECT_TRUE(found.R.isApprox(truth.R, 1e-9));
  EXPECT_NEAR((found.t - truth.t).norm(), 0.0, 1e-9);
  EXPECT_EQ(found.s, 1.0);
}

TEST(Alignment, MirroredPointsStillGiveAProperRotation) {
  std::mt19937 rng(3);
  const Eigen::Matrix3Xd source = randomPoints(rng, 30);
  Eigen::Matrix3Xd mirrored = source;
  mirrored.row(2) *= -1.0;
  const Sim3 found = umeyamaAlignment(source, mirrored, true);
  EXPECT_NEAR(found.R.determinant(), 1.0, 1e-12);
  EXPECT_TRUE(std::isfinite(found.s));
}

TEST(Alignment, DegenerateInputIsAClearError) {
  Eigen::Matrix3Xd two(3, 2);
  two << 0, 1, 0, 0, 0, 0;
  EXPECT_THROW(umeyamaAlignment(two, two, false), core::Error);
  Eigen::Matrix3Xd line(3, 10);
  for (int i = 0; i < 10; ++i)
    line.col(i) = Eigen::Vector3d(1, 2, 3) * i + Eigen::Vector3d(4, 5, 6);
  EXPECT_THROW(umeyamaAlignment(line, line, true), core::Error);
  const Eigen::Matrix3Xd same = Eigen::Matrix3Xd::Ones(3, 10);
  EXPECT_THROW(umeyamaAlignment(same, same, true), core::Error);
  EXPECT_THROW(
      umeyamaAlignment(Eigen::Matrix3Xd::Random(3, 5), Eigen::Matrix3Xd::Random(3, 4), false),
      core::Error);
  try {
    umeyamaAlignment(line, line, true);
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("collinear"), std::string::npos);
  }
}

TEST(Alignment, ParseAndPrintNames) {
  EXPECT_EQ(parseAlignment("none"), Alignment::none);
  EXPECT_EQ(parseAlignment("se3"), Alignment::se3);
  EXPECT_EQ(parseAlignment("sim3"), Alignment::sim3);
  EXPECT_EQ(toString(Alignment::sim3), "sim3");
  EXPECT_THROW(parseAlignment("SE3"), core::Error);
  EXPECT_THROW(parseAlignment(""), core::Error);
}

TEST(Alignment, TransformedScalesPositionsAndRotatesOrientations) {
  const core::Trajectory path = test::wavyPath(20);
  Sim3 S;
  S.R = core::expSO3(Eigen::Vector3d(0.1, -0.4, 1.2));
  S.t = Eigen::Vector3d(3, -2, 1);
  S.s = 2.5;
  const core::Trajectory moved = transformed(path, S);
  ASSERT_EQ(moved.size(), path.size());
  for (std::size_t i = 0; i < path.size(); ++i) {
    EXPECT_EQ(moved.stamp(i), path.stamp(i));
    EXPECT_TRUE(moved.pose(i).translation().isApprox(S.s * S.R * path.pose(i).translation() + S.t));
    EXPECT_TRUE(moved.pose(i).linear().isApprox(S.R * path.pose(i).linear()));
  }
}

TEST(Alignment, ComputeAlignmentUndoesAKnownMotion) {
  const core::Trajectory gt = test::wavyPath(60);
  Sim3 S_est_gt;
  S_est_gt.R = core::expSO3(Eigen::Vector3d(0.3, 0.2, -0.9));
  S_est_gt.t = Eigen::Vector3d(-5, 4, 2);
  S_est_gt.s = 0.5;
  const core::Trajectory est = transformed(gt, S_est_gt);
  const Association pairs = associateByIndex(est, gt);
  EXPECT_TRUE(computeAlignment(pairs, Alignment::none).R.isIdentity());
  const Sim3 S = computeAlignment(pairs, Alignment::sim3);
  EXPECT_NEAR(S.s, 2.0, 1e-9);
  EXPECT_TRUE(S.R.isApprox(S_est_gt.R.transpose(), 1e-9));
  const core::Trajectory back = transformed(est, S);
  for (std::size_t i = 0; i < gt.size(); ++i) {
    EXPECT_NEAR((back.pose(i).translation() - gt.pose(i).translation()).norm(), 0.0, 1e-9);
  }
}

}  // namespace
}  // namespace dcl::eval
