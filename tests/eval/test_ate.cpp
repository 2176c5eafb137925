#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/ate.hpp>

#include "test_support.hpp"

namespace dcl::eval {
namespace {

void expectStatisticsNear(const Statistics& s, const nlohmann::json& ref, double rel) {
  EXPECT_EQ(s.count, ref.at("count").get<std::size_t>());
  EXPECT_TRUE(test::near(s.rmse, ref.at("rmse").get<double>(), rel)) << s.rmse;
  EXPECT_TRUE(test::near(s.mean, ref.at("mean").get<double>(), rel)) << s.mean;
  EXPECT_TRUE(test::near(s.median, ref.at("median").get<double>(), rel)) << s.median;
  EXPECT_TRUE(test::near(s.std, ref.at("std").get<double>(), rel)) << s.std;
  EXPECT_TRUE(test::near(s.min, ref.at("min").get<double>(), rel, 1e-9)) << s.min;
  EXPECT_TRUE(test::near(s.max, ref.at("max").get<double>(), rel)) << s.max;
}

TEST(Ate, IdenticalTrajectoriesGiveZero) {
  const core::Trajectory gt = test::wavyPath(100);
  for (const Alignment a : {Alignment::none, Alignment::se3, Alignment::sim3}) {
    const AteResult r = computeAte(associateByIndex(gt, gt), a);
    EXPECT_EQ(r.pairs, 100u);
    EXPECT_EQ(r.alignment, a);
    EXPECT_NEAR(r.translation_m.max, 0.0, 1e-9);
    EXPECT_NEAR(r.rotation_deg.max, 0.0, 1e-6);
  }
}

TEST(Ate, ConstantOffsetWithoutAlignmentIsItsLength) {
  const core::Trajectory gt = test::wavyPath(80);
  core::Trajectory est = gt;
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(1.0, 2.0, 2.0);
  est.transformWorld(shift);
  const AteResult none = computeAte(associateByIndex(est, gt), Alignment::none);
  EXPECT_NEAR(none.translation_m.rmse, 3.0, 1e-12);
  EXPECT_NEAR(none.translation_m.std, 0.0, 1e-12);
  EXPECT_NEAR(none.rotation_deg.max, 0.0, 1e-9);
  const AteResult se3 = computeAte(associateByIndex(est, gt), Alignment::se3);
  EXPECT_NEAR(se3.translation_m.max, 0.0, 1e-9);
  EXPECT_NEAR((se3.S_gt_est.t + shift.translation()).norm(), 0.0, 1e-9);
}

TEST(Ate, BodyRotationShowsAsRotationErrorOnly) {
  const core::Trajectory gt = test::wavyPath(50);
  core::Trajectory est = gt;
  const Eigen::Vector3d axis = Eigen::Vector3d(1, -2, 0.5).normalized();
  est.transformBody(
      core::makePose(Eigen::Vector3d::Zero(), core::expSO3(core::deg2rad(5.0) * axis)));
  const AteResult r = computeAte(associateByIndex(est, gt), Alignment::none);
  EXPECT_NEAR(r.rotation_deg.min, 5.0, 1e-9);
  EXPECT_NEAR(r.rotation_deg.max, 5.0, 1e-9);
  EXPECT_NEAR(r.translation_m.max, 0.0, 1e-12);
}

TEST(Ate, KnownPerturbationGivesKnownStatistics) {
  // Alternate +d / -d along z on every pose: every translation error is d, with no alignment.
  const core::Trajectory gt = test::wavyPath(40);
  core::Trajectory est = gt;
  for (std::size_t i = 0; i < est.size(); ++i) {
    est.pose(i).translation().z() += (i % 2 == 0 ? 0.25 : -0.25);
  }
  const AteResult r = computeAte(associateByIndex(est, gt), Alignment::none);
  EXPECT_NEAR(r.translation_m.rmse, 0.25, 1e-12);
  EXPECT_NEAR(r.translation_m.mean, 0.25, 1e-12);
  EXPECT_NEAR(r.translation_m.median, 0.25, 1e-12);
}

TEST(Ate, Sim3UndoesScaleRotationAndTranslation) {
  const core::Trajectory gt = test::wavyPath(120);
  Sim3 S;
  S.R = core::expSO3(Eigen::Vector3d(0.4, -0.1, 2.0));
  S.t = Eigen::Vector3d(10, 20, -3);
  S.s = 0.3;
  const core::Trajectory est = transformed(gt, S);
  const Association pairs = associateByIndex(est, gt);
  const AteResult sim3 = computeAte(pairs, Alignment::sim3);
  EXPECT_NEAR(sim3.translation_m.max, 0.0, 1e-9);
  EXPECT_NEAR(sim3.rotation_deg.max, 0.0, 1e-6);
  EXPECT_NEAR(sim3.S_gt_est.s, 1.0 / 0.3, 1e-9);
  EXPECT_GT(computeAte(pairs, Alignment::se3).translation_m.rmse, 1.0);
}

TEST(Ate, ByTimestampFromTrajectories) {
  const core::Trajectory gt = test::wavyPath(100, 5.0);
  core::Trajectory est;
  for (std::size_t i = 0; i < gt.size(); i += 3) est.push_back(gt.stamp(i) + 0.004, gt.pose(i));
  AteOptions options;
  options.alignment = Alignment::none;
  const AteResult r = computeAte(est, gt, options);
  EXPECT_EQ(r.pairs, est.size());
  EXPECT_NEAR(r.translation_m.max, 0.0, 1e-12);
}

TEST(Ate, MultiRobotUsesTheReferenceRobotsAlignmentForAll) {
  const core::Trajectory gt_a = test::wavyPath(60);
  core::Trajectory gt_b = test::wavyPath(60, 100.0);
  gt_b.transformWorld(
      core::makePose(Eigen::Vector3d(30, 0, 0), core::expSO3(Eigen::Vector3d(0, 0, 1))));
  // Both robots' estimates live in one map frame, off the ground truth's by one motion.
  const Eigen::Isometry3d T_map_world =
      core::makePose(Eigen::Vector3d(1, 2, 3), core::expSO3(Eigen::Vector3d(0.2, 0.1, -0.5)));
  core::Trajectory est_a = gt_a;
  core::Trajectory est_b = gt_b;
  est_a.transformWorld(T_map_world);
  est_b.transformWorld(T_map_world);
  est_b.transformWorld(core::makePose(Eigen::Vector3d(0, 0, 0.5), Eigen::Matrix3d::Identity()));
  const std::vector<Association> robots{associateByIndex(est_a, gt_a),
                                        associateByIndex(est_b, gt_b)};
  const MultiRobotAteResult r = computeMultiRobotAte(robots);
  ASSERT_EQ(r.robots.size(), 2u);
  EXPECT_NEAR(r.robots[0].translation_m.max, 0.0, 1e-9);
  // Robot b keeps its extra 0.5 m: it is not aligned on its own.
  EXPECT_NEAR(r.robots[1].translation_m.min, 0.5, 1e-9);
  EXPECT_NEAR(r.robots[1].translation_m.max, 0.5, 1e-9);
  EXPECT_EQ(r.pooled.pairs, 120u);
  EXPECT_NEAR(r.pooled.translation_m.rmse, std::sqrt(0.5 * 0.25), 1e-9);
  EXPECT_NEAR(r.pooled.translation_m.median, 0.25, 1e-9);
  EXPECT_THROW(computeMultiRobotAte(robots, {Alignment::se3, 2}), core::Error);
  EXPECT_THROW(computeMultiRobotAte({}), core::Error);
}

TEST(Ate, MatchesTheReferenceScriptOnKitti00) {
  const core::Trajectory gt = test::readKitti(test::evoData("KITTI_00_gt.txt"));
  const core::Trajectory est = test::readKitti(test::evoData("KITTI_00_ORB.txt"));
  const Association pairs = associateByIndex(est, gt);
  for (const char* name : {"sim3", "se3", "none"}) {
    const auto ref = test::runReference(
        std::string("ate ") + test::kittiArguments("KITTI_00_ORB.txt") + " --align " + name);
    ASSERT_TRUE(ref) << "/usr/bin/python3 with numpy not available (scripts/setup installs it)";
    ASSERT_FALSE(ref->is_null()) << "the reference script failed";
    const AteResult r = computeAte(pairs, parseAlignment(name));
    EXPECT_EQ(r.pairs, ref->at("pairs").get<std::size_t>());
    expectStatisticsNear(r.translation_m, ref->at("translation_m"), 1e-9);
    expectStatisticsNear(r.rotation_deg, ref->at("rotation_deg"), 1e-9);
    EXPECT_NEAR(r.S_gt_est.s, ref->at("scale").get<double>(), 1e-12);
  }
}

TEST(Ate, MatchesTheReferenceScriptOnTumPair) {
  const core::Trajectory gt = test::readTum(test::evoData("freiburg1_xyz-groundtruth.txt"));
  const core::Trajectory est = test::readTum(test::evoData("freiburg1_xyz-rgbdslam.txt"));
  const auto ref = test::runReference(
      "ate --gt '" + test::evoData("freiburg1_xyz-groundtruth.txt") + "' --est '" +
      test::evoData("freiburg1_xyz-rgbdslam.txt") + "' --format tum --align se3");
  ASSERT_TRUE(ref) << "/usr/bin/python3 with numpy not available (scripts/setup installs it)";
  ASSERT_FALSE(ref->is_null()) << "the reference script failed";
  AteOptions options;
  options.alignment = Alignment::se3;
  const AteResult r = computeAte(est, gt, options);
  EXPECT_EQ(r.pairs, 785u);
  expectStatisticsNear(r.translation_m, ref->at("translation_m"), 1e-9);
  expectStatisticsNear(r.rotation_deg, ref->at("rotation_deg"), 1e-9);
}

}  // namespace
}  // namespace dcl::eval
