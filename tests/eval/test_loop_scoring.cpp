#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/se3.hpp>
#include <dcl/eval/loop_scoring.hpp>

#include "test_support.hpp"

namespace dcl::eval {
namespace {

/// A relative pose: `t` (m), then a rotation of `deg` about `axis`.
Eigen::Isometry3d offset(const Eigen::Vector3d& t, double deg, const Eigen::Vector3d& axis) {
  return core::makePose(t,
                        Eigen::Matrix3d(Eigen::AngleAxisd(core::deg2rad(deg), axis.normalized())));
}

TEST(LoopScoring, ErrorIsTheMeasurementAgainstTheTrueRelativePose) {
  // KITTI 00 closes its loop where it started: frame 4447 is 1.2 m from frame 0.
  const core::Trajectory gt = test::readKitti(test::evoData("KITTI_00_gt.txt"));
  const Eigen::Isometry3d& T_world_a = gt.pose(4447);
  const Eigen::Isometry3d& T_world_b = gt.pose(0);
  const Eigen::Isometry3d T_a_b = T_world_a.inverse() * T_world_b;
  const LoopError exact = loopError(T_a_b, T_world_a, T_world_b);
  EXPECT_NEAR(exact.translation_m, 0.0, 1e-9);
  EXPECT_NEAR(exact.rotation_deg, 0.0, 1e-6);
  const LoopError off =
      loopError(T_a_b * offset({0.3, 0.4, 0.0}, 1.5, {1, 2, 3}), T_world_a, T_world_b);
  EXPECT_NEAR(off.translation_m, 0.5, 1e-6);  // KITTI's rotations: 9 digits
  EXPECT_NEAR(off.rotation_deg, 1.5, 1e-6);
}

TEST(LoopScoring, CorrectWithinTheToleranceOnBothCounts) {
  const LoopTolerance tolerance;  // 1 m, 2 deg
  EXPECT_TRUE(isCorrect({0.0, 0.0}, tolerance));
  EXPECT_TRUE(isCorrect({1.0, 2.0}, tolerance));
  EXPECT_FALSE(isCorrect({1.01, 0.0}, tolerance));
  EXPECT_FALSE(isCorrect({0.0, 2.01}, tolerance));
  EXPECT_TRUE(isCorrect({1.5, 0.1}, {.max_error_m = 2.0, .max_error_deg = 0.5}));
}

TEST(LoopScoring, CountsEachStageOfAConstructedCandidateSet) {
  // Candidates on KITTI 00: real revisits (frames 0 and 4447, 200 and 1635,
  // 800 and 3735, 1600 and 156) and places hundreds of metres apart that a
  // descriptor mistook (2600 and 100, 3300 and 700), each measured right or wrong.
  const core::Trajectory gt = test::readKitti(test::evoData("KITTI_00_gt.txt"));
  struct Case {
    std::size_t a, b;
    bool verified;
    Eigen::Isometry3d measurement_error;
    bool kept, withdrawn;
  };
  const Eigen::Isometry3d right = offset({0.1, -0.05, 0.02}, 0.3, {0, 0, 1});
  const Eigen::Isometry3d wrong = offset({4.0, 1.0, 0.0}, 10.0, {0, 0, 1});
  const std::vector<Case> cases{
      {0, 4447, true, right, true, false},      // kept, correct
      {200, 1635, true, right, true, false},    // kept, correct
      {800, 3735, true, right, false, true},    // correct, withdrawn by the check
      {1600, 156, true, wrong, false, false},   // a revisit measured wrong, rejected by PCM
      {1600, 156, false, right, false, false},  // a revisit the verification refused
      {2600, 100, true, wrong, true, false},    // a wrong loop kept
      {3300, 700, true, wrong, false, true},    // a wrong loop withdrawn
      {3300, 700, false, wrong, false, false},  // refused
  };
  std::vector<CandidateLoop> candidates;
  for (const Case& c : cases) {
    const Eigen::Isometry3d& T_world_a = gt.pose(c.a);
    const Eigen::Isometry3d& T_world_b = gt.pose(c.b);
    const Eigen::Isometry3d measured = T_world_a.inverse() * T_world_b * c.measurement_error;
    const LoopError error = loopError(measured, T_world_a, T_world_b);
    const double distance = (T_world_a.translation() - T_world_b.translation()).norm();
    candidates.push_back(
        {distance, c.verified, c.verified && isCorrect(error, {}), c.kept, c.withdrawn});
  }
  const LoopCounts n = countLoops(candidates, 3.0);
  EXPECT_EQ(n.candidates, 8u);
  EXPECT_EQ(n.candidates_true, 5u);
  EXPECT_EQ(n.verified, 6u);
  EXPECT_EQ(n.verified_correct, 3u);
  EXPECT_EQ(n.verified_wrong, 3u);
  EXPECT_EQ(n.kept, 3u);
  EXPECT_EQ(n.kept_correct, 2u);
  EXPECT_EQ(n.kept_wrong, 1u);
  EXPECT_EQ(n.withdrawn, 2u);
  EXPECT_EQ(n.withdrawn_correct, 1u);
  EXPECT_DOUBLE_EQ(n.precision, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(n.recall, 2.0 / 3.0);
  // Within 1.1 m: every revisit but frames 0 and 4447 (1.23 m apart).
  EXPECT_EQ(countLoops(candidates, 1.1).candidates_true, 4u);
}

TEST(LoopScoring, NothingKeptIsPreciseAndNothingCorrectRecallsNothing) {
  const LoopCounts none = countLoops({}, 3.0);
  EXPECT_EQ(none.candidates, 0u);
  EXPECT_EQ(none.precision, 1.0);
  EXPECT_EQ(none.recall, 0.0);
  // Flags of a candidate verification refused are not counted.
  const LoopCounts refused = countLoops({{1.0, false, true, true, true}}, 3.0);
  EXPECT_EQ(refused.candidates_true, 1u);
  EXPECT_EQ(refused.verified, 0u);
  EXPECT_EQ(refused.kept, 0u);
  EXPECT_EQ(refused.withdrawn, 0u);
  EXPECT_EQ(refused.precision, 1.0);
  EXPECT_EQ(refused.recall, 0.0);
}

}  // namespace
}  // namespace dcl::eval
