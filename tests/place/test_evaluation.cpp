// The precision-recall sweep on hand-made cases, and the readers of the
// LiDAR-Iris authors' published KITTI files on the real files.

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include <dcl/core/error.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/place/evaluation.hpp>

namespace dcl::place {
namespace {

std::string loopGtPath(const std::string& name) {
  return std::string(DCL_DATA_DIR) + "/trajectories/kitti_loop_closure_gt/" + name;
}

TEST(PrCurve, HandMadeCase) {
  // distance, true loop, has revisit: two true loops, then a wrong one, then a
  // true one; one revisit never found (its candidate is wrong).
  const std::vector<QueryOutcome> outcomes = {{0.40, true, true},
                                              {0.10, true, true},
                                              {0.20, true, true},
                                              {0.30, false, true},
                                              {0.50, false, false}};
  const PrCurve curve = computePrCurve(outcomes);
  EXPECT_EQ(curve.queries, 5u);
  EXPECT_EQ(curve.positives, 4u);
  ASSERT_EQ(curve.points.size(), 5u);
  EXPECT_DOUBLE_EQ(curve.points[0].threshold, 0.10);
  EXPECT_DOUBLE_EQ(curve.points[0].recall, 0.25);
  EXPECT_DOUBLE_EQ(curve.points[2].precision, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(curve.points[3].recall, 0.75);
  EXPECT_EQ(curve.points[4].false_positives, 2u);
  EXPECT_DOUBLE_EQ(curve.recall_at_full_precision, 0.5);
  ASSERT_TRUE(curve.threshold_at_full_precision);
  EXPECT_DOUBLE_EQ(*curve.threshold_at_full_precision, 0.25);
  // F1 at 0.4: precision 3/4, recall 3/4.
  EXPECT_NEAR(curve.max_f1, 0.75, 1e-12);
}

TEST(PrCurve, TiesCountTheWrongCandidateFirst) {
  const PrCurve curve = computePrCurve({{0.2, true, true}, {0.2, false, true}});
  ASSERT_EQ(curve.points.size(), 1u);
  EXPECT_EQ(curve.points[0].true_positives, 1u);
  EXPECT_EQ(curve.points[0].false_positives, 1u);
  EXPECT_DOUBLE_EQ(curve.recall_at_full_precision, 0.0);
  EXPECT_FALSE(curve.threshold_at_full_precision);
}

TEST(PrCurve, AllTrueAndEmpty) {
  const PrCurve all = computePrCurve({{0.1, true, true}, {0.3, true, true}});
  EXPECT_DOUBLE_EQ(all.recall_at_full_precision, 1.0);
  ASSERT_TRUE(all.threshold_at_full_precision);
  EXPECT_GT(*all.threshold_at_full_precision, 0.3);
  const PrCurve none = computePrCurve({});
  EXPECT_TRUE(none.points.empty());
  EXPECT_DOUBLE_EQ(none.recall_at_full_precision, 0.0);
}

TEST(PublishedFiles, GroundTruthIsFourMetresInTheGroundPlaneNumberedFromOne) {
  const LoopGroundTruth gt = readLoopGroundTruth(loopGtPath("gt05.txt"));
  const core::Trajectory poses =
      io::readKittiPoses(std::string(DCL_DATA_DIR) + "/trajectories/kitti_gt_poses/05.txt");
  ASSERT_EQ(gt.near.size(), poses.size());  // 2761 frames
  std::size_t pairs = 0;
  for (std::size_t i = 0; i < gt.near.size(); ++i) {
    for (std::size_t j : gt.near[i]) {
      // KITTI's camera frame: x right, y down, z forward; the ground plane is x-z.
      const Eigen::Vector3d d = poses.pose(i).translation() - poses.pose(j).translation();
      ASSERT_LT(std::hypot(d.x(), d.z()), 4.0 + 1e-6) << i << " " << j;
      ++pairs;
    }
  }
  EXPECT_GT(pairs, 20000u);
  EXPECT_TRUE(gt.isNear(1, 0));  // file line "2 1 3 4 ..."
  EXPECT_FALSE(gt.isNear(1, 1));
}

TEST(PublishedFiles, FlagsAgreeWithGroundTruthAndRecallsMatch) {
  // Recall at 100 % precision of the published results (see evaluation.hpp):
  // 00: 734 of 791 revisits, 05: 401 of 437, 08: 151 of 332.
  const std::vector<std::pair<std::string, double>> expected = {
      {"00", 734.0 / 791.0}, {"05", 401.0 / 437.0}, {"08", 151.0 / 332.0}};
  for (const auto& [seq, recall] : expected) {
    const LoopGroundTruth gt = readLoopGroundTruth(loopGtPath("gt" + seq + ".txt"));
    const auto matches = readPublishedMatches(loopGtPath("lidar_iris_result_" + seq + ".txt"));
    ASSERT_FALSE(matches.empty());
    for (const PublishedMatch& m : matches) {
      ASSERT_EQ(m.flag, gt.isNear(m.query, m.match)) << seq << " query " << m.query;
      ASSERT_GE(m.query, m.match + 300);
    }
    const PrCurve curve = evaluatePublished(gt, matches);
    EXPECT_NEAR(curve.recall_at_full_precision, recall, 1e-12) << seq;
    EXPECT_EQ(curve.queries, matches.size());
  }
}

TEST(PublishedFiles, MalformedFilesNameTheLine) {
  const std::string path =
      ::testing::TempDir() + "/dcl_bad_result_" + std::to_string(::getpid()) + ".txt";
  std::ofstream(path) << "301 1 0.43 0\n302 2 zero 1\n";
  try {
    readPublishedMatches(path);
    FAIL() << "no error";
  } catch (const core::FileError& e) {
    EXPECT_EQ(e.location().line, 2u);
  }
  std::ofstream(path) << "0 1 0.43 0\n";
  EXPECT_THROW(readPublishedMatches(path), core::FileError);
  std::ofstream(path) << "3 1 0.43 2\n";
  EXPECT_THROW(readPublishedMatches(path), core::FileError);
  EXPECT_THROW(readLoopGroundTruth(path + ".missing"), core::FileError);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace dcl::place
