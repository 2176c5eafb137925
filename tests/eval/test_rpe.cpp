#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/rpe.hpp>
#include <dcl/io/pose_file.hpp>

#include "test_support.hpp"

namespace dcl::eval {
namespace {

// A straight drive along x, one pose a metre (stamps 0, 1, 2, ...).
core::Trajectory straightLine(std::size_t n, double step = 1.0) {
  core::Trajectory trajectory;
  for (std::size_t i = 0; i < n; ++i) {
    trajectory.push_back(static_cast<double>(i),
                         core::makePose(Eigen::Vector3d(step * static_cast<double>(i), 0, 0),
                                        Eigen::Matrix3d::Identity()));
  }
  return trajectory;
}

void expectRpeStatisticsNear(const Statistics& s, const nlohmann::json& ref, double rel) {
  EXPECT_EQ(s.count, ref.at("count").get<std::size_t>());
  for (const auto& [name, value] :
       {std::pair{"rmse", s.rmse}, std::pair{"mean", s.mean}, std::pair{"median", s.median},
        std::pair{"std", s.std}, std::pair{"min", s.min}, std::pair{"max", s.max}}) {
    EXPECT_TRUE(test::near(value, ref.at(name).get<double>(), rel, 1e-12))
        << name << ": " << value << " vs " << ref.at(name).get<double>();
  }
}

TEST(Rpe, PairsByIndexFollowEvo) {
  EXPECT_EQ(pairsByIndex(7, 3, false), (std::vector<IndexPair>{{0, 3}, {3, 6}}));
  EXPECT_EQ(pairsByIndex(7, 3, true), (std::vector<IndexPair>{{0, 3}, {1, 4}, {2, 5}, {3, 6}}));
  EXPECT_EQ(pairsByIndex(5, 1, false).size(), 4u);
  EXPECT_TRUE(pairsByIndex(3, 5, false).empty());
  EXPECT_THROW(pairsByIndex(3, 0, false), core::Error);
}

TEST(Rpe, PairsByPathFollowEvo) {
  const core::Trajectory line = straightLine(12);  // path 0, 1, ..., 11 m
  // Consecutive: the kept poses are where 3 m have been travelled since the last kept one
  // (3, 6, 9); like evo, pose 0 is not among them.
  EXPECT_EQ(pairsByPath(line, 3.0, 0.0, false), (std::vector<IndexPair>{{3, 6}, {6, 9}}));
  // All pairs: the nearest path length to 3.2 m is 3 m, within a 0.3 m tolerance.
  const auto all = pairsByPath(line, 3.2, 0.3, true);
  ASSERT_EQ(all.size(), 9u);
  EXPECT_EQ(all.front(), (IndexPair{0, 3}));
  EXPECT_EQ(all.back(), (IndexPair{8, 11}));
  EXPECT_EQ(pairsByPath(line, 3.5, 0.5, true).size(), 9u);  // 3.5: 3 and 4 m tie, 3 wins
  EXPECT_EQ(pairsByPath(line, 3.5, 0.5, true).front(), (IndexPair{0, 3}));
  EXPECT_TRUE(pairsByPath(line, 3.5, 0.1, true).empty());
}

TEST(Rpe, RelativeErrorOfAConstructedCase) {
  // The estimate's second step is 10 cm too long and turned 2 degrees about z.
  const Eigen::Isometry3d Q_i =
      core::makePose(Eigen::Vector3d(0, 0, 0), Eigen::Matrix3d::Identity());
  const Eigen::Isometry3d Q_j =
      core::makePose(Eigen::Vector3d(1, 0, 0), Eigen::Matrix3d::Identity());
  const Eigen::Isometry3d P_i =
      core::makePose(Eigen::Vector3d(5, 5, 0), core::expSO3(Eigen::Vector3d(0, 0, 1)));
  const Eigen::Isometry3d P_j =
      P_i * core::makePose(Eigen::Vector3d(1.1, 0, 0),
                           core::expSO3(Eigen::Vector3d(0, 0, core::deg2rad(2.0))));
  const Eigen::Isometry3d E = relativeError(Q_i, Q_j, P_i, P_j);
  EXPECT_NEAR(E.translation().norm(), 0.1, 1e-12);
  EXPECT_NEAR(core::rad2deg(core::rotationAngle(E.linear())), 2.0, 1e-9);
}

TEST(Rpe, ConstructedDriftGivesKnownErrors) {
  // Every estimated step is 1.1 m instead of 1 m: 0.1 m error per frame, 0.2 m per 2 frames.
  const core::Trajectory gt = straightLine(21);
  const core::Trajectory est = straightLine(21, 1.1);
  const Association pairs = associateByIndex(est, gt);
  RpeOptions options;
  const RpeResult one = computeRpe(pairs, options);
  EXPECT_EQ(one.pairs.size(), 20u);
  EXPECT_NEAR(one.translation_m.min, 0.1, 1e-12);
  EXPECT_NEAR(one.translation_m.max, 0.1, 1e-12);
  EXPECT_NEAR(one.rotation_deg.max, 0.0, 1e-12);
  EXPECT_FALSE(one.kitti.has_value());  // a 20 m drive has no 100 m segment
  options.delta = 2;
  const RpeResult two = computeRpe(pairs, options);
  EXPECT_EQ(two.pairs.size(), 10u);
  EXPECT_NEAR(two.translation_m.rmse, 0.2, 1e-12);
  // A straight line is collinear: Sim(3) alignment has no unique rotation and says so.
  options.alignment = Alignment::sim3;
  EXPECT_THROW(computeRpe(pairs, options), core::Error);
}

TEST(Rpe, Sim3AlignmentUndoesAScaledEstimate) {
  const core::Trajectory gt = test::wavyPath(100);
  Sim3 S;
  S.R = core::expSO3(Eigen::Vector3d(0.3, 0.2, 0.1));
  S.s = 1.7;
  const Association pairs = associateByIndex(transformed(gt, S), gt);
  RpeOptions options;
  options.delta = 3;
  EXPECT_GT(computeRpe(pairs, options).translation_m.max, 0.01);
  options.alignment = Alignment::se3;
  EXPECT_GT(computeRpe(pairs, options).translation_m.max, 0.01);
  options.alignment = Alignment::sim3;
  const RpeResult r = computeRpe(pairs, options);
  EXPECT_NEAR(r.translation_m.max, 0.0, 1e-9);
  EXPECT_NEAR(r.rotation_deg.max, 0.0, 1e-6);
  EXPECT_NEAR(r.S_gt_est.s, 1.0 / 1.7, 1e-9);
}

TEST(Rpe, InvalidDeltaIsAnError) {
  const Association pairs = associateByIndex(straightLine(5), straightLine(5));
  RpeOptions options;
  options.delta = 1.5;
  EXPECT_THROW(computeRpe(pairs, options), core::Error);
  options.delta = 10;
  EXPECT_THROW(computeRpe(pairs, options), core::Error);
  options.delta_unit = DeltaUnit::meters;
  options.delta = -1.0;
  EXPECT_THROW(computeRpe(pairs, options), core::Error);
  EXPECT_EQ(parseDeltaUnit("m"), DeltaUnit::meters);
  EXPECT_THROW(parseDeltaUnit("seconds"), core::Error);
}

TEST(Rpe, KittiMetricOfAScaledStraightDrive) {
  // 1 m a frame for 1000 m; the estimate drives 1.01 m a frame. A segment of length L ends at
  // the first frame more than L metres on, L + 1 frames later: error 0.01 (L + 1) m.
  const core::Trajectory gt = straightLine(1001);
  const core::Trajectory est = straightLine(1001, 1.01);
  const auto kitti = computeKittiMetric(associateByIndex(est, gt));
  ASSERT_TRUE(kitti.has_value());
  ASSERT_EQ(kitti->per_length.size(), 8u);
  double sum = 0.0;
  std::size_t count = 0;
  for (const KittiLength& l : kitti->per_length) {
    EXPECT_NEAR(l.translation_percent, (l.length_m + 1.0) / l.length_m, 1e-9) << l.length_m;
    EXPECT_NEAR(l.rotation_deg_per_100m, 0.0, 1e-9);
    // Starts 0, 10, ... up to the last start with more than L metres after it.
    EXPECT_EQ(l.segments, static_cast<std::size_t>((999.0 - l.length_m) / 10.0) + 1) << l.length_m;
    sum += l.translation_percent * static_cast<double>(l.segments);
    count += l.segments;
  }
  EXPECT_EQ(kitti->segments, count);
  EXPECT_NEAR(kitti->translation_percent, sum / static_cast<double>(count), 1e-9);
}

TEST(Rpe, KittiMetricNeedsASegmentLongEnough) {
  const core::Trajectory gt = straightLine(101);  // exactly 100 m: no frame lies beyond 100 m
  EXPECT_FALSE(computeKittiMetric(associateByIndex(gt, gt)).has_value());
  EXPECT_TRUE(
      computeKittiMetric(associateByIndex(straightLine(102), straightLine(102))).has_value());
}

TEST(Rpe, KittiMetricOfGroundTruthAgainstItselfIsZero) {
  const core::Trajectory gt = test::readKitti(test::evoData("KITTI_00_gt.txt"));
  const auto kitti = computeKittiMetric(associateByIndex(gt, gt));
  ASSERT_TRUE(kitti.has_value());
  EXPECT_GT(kitti->segments, 3000u);
  EXPECT_NEAR(kitti->translation_percent, 0.0, 1e-9);
  EXPECT_NEAR(kitti->rotation_deg_per_100m, 0.0, 1e-3);  // acos of a trace rounded near 1
}

TEST(Rpe, KittiMetricOfOrbSlam2OnKitti00IsPlausible) {
  const core::Trajectory gt = test::readKitti(test::evoData("KITTI_00_gt.txt"));
  const core::Trajectory est = test::readKitti(test::evoData("KITTI_00_ORB.txt"));
  const auto kitti = computeKittiMetric(associateByIndex(est, gt));
  ASSERT_TRUE(kitti.has_value());
  // ORB-SLAM2 (stereo) reports 0.70 % and 0.25 deg/100 m on sequence 00.
  EXPECT_NEAR(kitti->translation_percent, 0.70, 0.01);
  EXPECT_NEAR(kitti->rotation_deg_per_100m, 0.25, 0.01);
  EXPECT_NEAR(kitti->rotation_deg_per_m * 100.0, kitti->rotation_deg_per_100m, 1e-12);
  EXPECT_EQ(kitti->per_length.size(), 8u);
}

TEST(Rpe, MatchesTheReferenceScriptOnKitti00) {
  const core::Trajectory gt = test::readKitti(test::evoData("KITTI_00_gt.txt"));
  const core::Trajectory est = test::readKitti(test::evoData("KITTI_00_ORB.txt"));
  const Association pairs = associateByIndex(est, gt);
  for (const char* name : {"none", "se3", "sim3"}) {
    for (const int delta : {1, 10}) {
      const auto ref = test::runReference("rpe " + test::kittiArguments("KITTI_00_ORB.txt") +
                                          " --align " + name + " --delta " + std::to_string(delta));
      ASSERT_TRUE(ref) << "/usr/bin/python3 with numpy not available (scripts/setup installs it)";
      ASSERT_FALSE(ref->is_null()) << "the reference script failed";
      RpeOptions options;
      options.alignment = parseAlignment(name);
      options.delta = delta;
      const RpeResult r = computeRpe(pairs, options);
      EXPECT_EQ(r.pairs.size(), ref->at("pairs").get<std::size_t>());
      expectRpeStatisticsNear(r.translation_m, ref->at("translation_m"), 1e-9);
      expectRpeStatisticsNear(r.rotation_deg, ref->at("rotation_deg"), 1e-7);
      ASSERT_TRUE(r.kitti.has_value());
      const auto& k = ref->at("kitti");
      EXPECT_EQ(r.kitti->segments, k.at("segments").get<std::size_t>());
      EXPECT_TRUE(test::near(r.kitti->translation_percent,
                             k.at("translation_percent").get<double>(), 1e-9));
      EXPECT_TRUE(test::near(r.kitti->rotation_deg_per_100m,
                             k.at("rotation_deg_per_100m").get<double>(), 1e-7));
    }
  }
}

TEST(Rpe, MatchesTheReferenceScriptWithOrthonormalizedRotations) {
  // Rotations projected onto SO(3) on both sides (the script's --orthonormalize).
  auto project = [](core::Trajectory t) {
    for (std::size_t i = 0; i < t.size(); ++i)
      t.pose(i).linear() = core::projectToSO3(t.pose(i).linear());
    return t;
  };
  const core::Trajectory gt = project(test::readKitti(test::evoData("KITTI_00_gt.txt")));
  const core::Trajectory est = project(test::readKitti(test::evoData("KITTI_00_ORB.txt")));
  const auto ref = test::runReference("rpe " + test::kittiArguments("KITTI_00_ORB.txt") +
                                      " --align se3 --delta 1 --orthonormalize");
  ASSERT_TRUE(ref) << "/usr/bin/python3 with numpy not available (scripts/setup installs it)";
  ASSERT_FALSE(ref->is_null()) << "the reference script failed";
  RpeOptions options;
  options.alignment = Alignment::se3;
  const RpeResult r = computeRpe(associateByIndex(est, gt), options);
  expectRpeStatisticsNear(r.translation_m, ref->at("translation_m"), 1e-9);
  expectRpeStatisticsNear(r.rotation_deg, ref->at("rotation_deg"), 1e-7);
  ASSERT_TRUE(r.kitti.has_value());
  EXPECT_TRUE(test::near(r.kitti->rotation_deg_per_100m,
                         ref->at("kitti").at("rotation_deg_per_100m").get<double>(), 1e-7));
}

TEST(Rpe, DclIoReadersMatchTheReference) {
  // The path of `dcl-slam eval`: dcl::io's readers (the 3x4 matrices as written, as evo), then
  // eval.
  const core::Trajectory gt = io::readKittiPoses(test::evoData("KITTI_00_gt.txt"));
  const core::Trajectory est = io::readKittiPoses(test::evoData("KITTI_00_ORB.txt"));
  const auto ref = test::runReference("rpe " + test::kittiArguments("KITTI_00_ORB.txt") +
                                      " --align sim3 --delta 1");
  ASSERT_TRUE(ref) << "/usr/bin/python3 with numpy not available (scripts/setup installs it)";
  ASSERT_FALSE(ref->is_null()) << "the reference script failed";
  RpeOptions options;
  options.alignment = Alignment::sim3;
  const RpeResult r = computeRpe(associateByIndex(est, gt), options);
  expectRpeStatisticsNear(r.translation_m, ref->at("translation_m"), 1e-9);
  expectRpeStatisticsNear(r.rotation_deg, ref->at("rotation_deg"), 1e-7);
  ASSERT_TRUE(r.kitti.has_value());
  EXPECT_TRUE(test::near(r.kitti->translation_percent,
                         ref->at("kitti").at("translation_percent").get<double>(), 1e-9));
  EXPECT_TRUE(test::near(r.kitti->rotation_deg_per_100m,
                         ref->at("kitti").at("rotation_deg_per_100m").get<double>(), 1e-7));
}

TEST(Rpe, MatchesTheReferenceScriptOnTumPair) {
  const std::string gt_file = test::evoData("freiburg1_xyz-groundtruth.txt");
  const std::string est_file = test::evoData("freiburg1_xyz-rgbdslam.txt");
  const auto ref = test::runReference("rpe --gt '" + gt_file + "' --est '" + est_file +
                                      "' --format tum --align sim3 --delta 5");
  ASSERT_TRUE(ref) << "/usr/bin/python3 with numpy not available (scripts/setup installs it)";
  ASSERT_FALSE(ref->is_null()) << "the reference script failed";
  RpeOptions options;
  options.alignment = Alignment::sim3;
  options.delta = 5;
  const RpeResult r = computeRpe(test::readTum(est_file), test::readTum(gt_file), options);
  expectRpeStatisticsNear(r.translation_m, ref->at("translation_m"), 1e-9);
  expectRpeStatisticsNear(r.rotation_deg, ref->at("rotation_deg"), 1e-7);
  EXPECT_FALSE(r.kitti.has_value());
  EXPECT_TRUE(ref->at("kitti").is_null());
}

}  // namespace
}  // namespace dcl::eval
