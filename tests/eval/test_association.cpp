#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/association.hpp>

#include "test_support.hpp"

namespace dcl::eval {
namespace {

core::Trajectory stamped(const std::vector<double>& stamps) {
  core::Trajectory trajectory;
  for (const double t : stamps) {
    trajectory.push_back(t, core::makePose(Eigen::Vector3d(t, 0, 0), Eigen::Matrix3d::Identity()));
  }
  return trajectory;
}

TEST(Association, RealTumPairMatchesWithinTolerance) {
  const core::Trajectory gt = test::readTum(test::evoData("freiburg1_xyz-groundtruth.txt"));
  const core::Trajectory est = test::readTum(test::evoData("freiburg1_xyz-rgbdslam.txt"));
  ASSERT_EQ(gt.size(), 3000u);
  ASSERT_EQ(est.size(), 788u);  // 789 lines, one a comment
  const Association pairs = associateByTimestamp(est, gt);
  // evo (and tests/eval/reference_metrics.py) find 785 of the 788 estimate stamps.
  EXPECT_EQ(pairs.size(), 785u);
  ASSERT_EQ(pairs.ground_truth.size(), pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    EXPECT_LE(std::abs(pairs.estimate.stamp(k) - pairs.ground_truth.stamp(k)), 0.01);
    EXPECT_EQ(pairs.estimate.stamp(k), est.stamp(pairs.estimate_index[k]));
    EXPECT_EQ(pairs.ground_truth.stamp(k), gt.stamp(pairs.ground_truth_index[k]));
  }
}

TEST(Association, ShorterIsMatchedIntoLongerByNearestStamp) {
  const core::Trajectory gt = stamped({0.0, 0.1, 0.2, 0.3, 0.4});
  const core::Trajectory est = stamped({0.104, 0.296, 0.5});
  const Association pairs = associateByTimestamp(est, gt, 0.01);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs.estimate_index, (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(pairs.ground_truth_index, (std::vector<std::size_t>{1, 3}));
}

TEST(Association, LongerEstimateIsSearchedAndMayRepeat) {
  // The ground truth is the shorter: each of its stamps takes the nearest estimate stamp.
  const core::Trajectory gt = stamped({1.0, 1.001});
  const core::Trajectory est = stamped({0.9, 1.0005, 1.1, 1.2});
  const Association pairs = associateByTimestamp(est, gt, 0.01);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs.estimate_index, (std::vector<std::size_t>{1, 1}));
  EXPECT_EQ(pairs.ground_truth_index, (std::vector<std::size_t>{0, 1}));
}

TEST(Association, TieGoesToTheEarlierStamp) {
  const core::Trajectory gt = stamped({0.0, 0.5, 1.0, 2.0});
  const core::Trajectory est = stamped({0.75});
  const Association pairs = associateByTimestamp(est, gt, 0.3);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs.ground_truth_index[0], 1u);
}

TEST(Association, UnsortedStampsGiveTheSameAsArgmin) {
  const core::Trajectory gt = stamped({0.3, 0.0, 0.2, 0.1, 0.4});
  const core::Trajectory est = stamped({0.099, 0.401});
  const Association pairs = associateByTimestamp(est, gt, 0.01);
  EXPECT_EQ(pairs.ground_truth_index, (std::vector<std::size_t>{3, 4}));
}

TEST(Association, OffsetShiftsTheEstimate) {
  const core::Trajectory gt = stamped({10.0, 10.1, 10.2, 10.3});
  const core::Trajectory est = stamped({0.0, 0.1, 0.2});
  EXPECT_THROW(associateByTimestamp(est, gt), core::Error);
  const Association pairs = associateByTimestamp(est, gt, 0.01, 10.0);
  EXPECT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs.ground_truth_index, (std::vector<std::size_t>{0, 1, 2}));
  // The same with the estimate the longer one (the offset then shifts the searched list).
  const Association swapped = associateByTimestamp(gt, est, 0.01, -10.0);
  EXPECT_EQ(swapped.size(), 3u);
  EXPECT_EQ(swapped.estimate_index, (std::vector<std::size_t>{0, 1, 2}));
}

TEST(Association, NoMatchNamesBothStampRanges) {
  const core::Trajectory gt = stamped({100.0, 101.0, 102.0});
  const core::Trajectory est = stamped({0.0, 1.0});
  try {
    associateByTimestamp(est, gt);
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("2 poses, stamps 0.000000 .. 1.000000"), std::string::npos) << what;
    EXPECT_NE(what.find("3 poses, stamps 100.000000 .. 102.000000"), std::string::npos) << what;
  }
}

TEST(Association, EmptyTrajectoryIsAnError) {
  EXPECT_THROW(associateByTimestamp(core::Trajectory{}, stamped({1.0})), core::Error);
  EXPECT_THROW(associateByIndex(core::Trajectory{}, core::Trajectory{}), core::Error);
}

TEST(Association, ByIndexPairsEqualLengths) {
  const core::Trajectory gt = test::readKitti(test::evoData("KITTI_00_gt.txt"));
  const core::Trajectory est = test::readKitti(test::evoData("KITTI_00_ORB.txt"));
  const Association pairs = associateByIndex(est, gt);
  EXPECT_EQ(pairs.size(), 4541u);
  EXPECT_EQ(pairs.estimate_index[4540], 4540u);
  EXPECT_TRUE(pairs.ground_truth.pose(7).isApprox(gt.pose(7)));
}

TEST(Association, ByIndexRejectsDifferentLengths) {
  try {
    associateByIndex(stamped({0, 1, 2}), stamped({0, 1}));
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("3 poses but the ground truth 2"), std::string::npos);
  }
}

TEST(Association, DispatchAndNames) {
  AssociationOptions options;
  options.mode = parseAssociationMode("index");
  EXPECT_EQ(associate(stamped({5, 6}), stamped({0, 1}), options).size(), 2u);
  EXPECT_EQ(toString(AssociationMode::timestamp), "timestamp");
  EXPECT_THROW(parseAssociationMode("nearest"), core::Error);
}

}  // namespace
}  // namespace dcl::eval
